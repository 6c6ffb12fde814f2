!> Projected Gauss-Seidel (PGS) for contact impulses with Coulomb friction.
!>
!> Each contact point c between bodies a and b carries an impulse P_c = lambda_n n + lambda_t
!> (applied +P to b, -P to a) with lambda_n >= 0 and |lambda_t| <= mu lambda_n (the friction
!> cone). One sweep visits every contact and, holding the others fixed, solves its own 3x3
!> problem exactly:
!>   - normal: lambda_n <- max(0, lambda_n - u_n / K_nn)      (no approach, no pull);
!>   - tangential: the impulse in the disc |lambda_t| <= mu lambda_n that dissipates the
!>     most kinetic energy (maximal dissipation): lambda_t - K_tt^(-1) u_t if it lies in the
!>     disc (stick), else the point of the circle minimising the energy, found as the
!>     trust-region step -(K_tt + nu I)^(-1) g with nu >= 0 (slide). Merely scaling the
!>     stick impulse back onto the circle would tilt friction away from the slip wherever
!>     K_tt is not isotropic (a box's corner), and a sliding box would brake too little;
!> with u the relative velocity at the contact and K = J M^(-1) J^T its 3x3 effective inverse
!> mass (translation and rotation of both bodies). Sweeps repeat until no body's velocity
!> (|dv| + |dw| times its reach to its contacts) changes by more than `tolerance` [m/s] in a
!> sweep, or the sweep cap. (The test is on the bodies' velocities, not on impulses: face-to-
!> face contacts give more points than the impulses need, so the impulses are not unique
!> and can drift between points while the velocities have converged.) Contacts are visited in the
!> order given: the caller sorts them bottom-up along gravity, so in a stack the load is
!> carried down in a few sweeps (the ordering half of shock propagation). Warm starts (the
!> impulses of the same contacts at the previous step) make a resting stack converge in one
!> or two sweeps.
!>
!> The result need not be exact for safety: conservative advancement catches any residual
!> approach as an ordinary event. It must be dissipative: each local normal step is a
!> projection and each tangential step moves towards stick, inside the cone.
module contact_solver
  use kinds, only: dp
  use vector_ops, only: cross
  use quaternion, only: quat_rotate, quat_rotate_inverse
  use body_state, only: bodies_t
  use impulse_solver, only: contact_t, group_members
  implicit none
  private
  public :: pgs_stats_t, pgs_setup_t, solve_contacts_pgs, tangent_basis, friction_step, decompose2

  type :: pgs_stats_t
    integer :: solves = 0              !< calls
    integer :: sweeps = 0              !< sweeps, summed
    integer :: max_sweeps_seen = 0
    integer :: cap_hits = 0            !< solves stopped by the sweep cap
  end type pgs_stats_t

  !> What a solve computes from the contacts and the bodies' poses only, per contact c: the
  !> basis (normal, two tangents), the 1x1 and 2x2 blocks of the effective inverse mass, the
  !> bodies' angular velocity change per unit impulse along each basis direction, the arms;
  !> and the moving bodies of the group with each one's reach.
  type :: pgs_setup_t
    logical :: ready = .false.
    real(dp), allocatable :: basis(:, :, :), k_tt(:, :, :), turn_a(:, :, :), turn_b(:, :, :)
    real(dp), allocatable :: arm_a(:, :), arm_b(:, :), reach(:)
    !> per contact: 1/(n.K n); the tangential velocity change per unit normal impulse (t1.K n,
    !> t2.K n); K_tt's inverse, eigenvalues (larger first) and its first eigenvector (the
    !> sliding solve's secular equation in closed form)
    real(dp), allocatable :: inv_k_nn(:), k_tn(:, :), inv_k_tt(:, :, :), eig_tt(:, :), axis_tt(:, :)
    integer, allocatable :: members(:), side(:, :)
    integer :: n_members = 0
  contains
    procedure :: free => setup_free
  end type pgs_setup_t

contains

  !> Two unit tangents completing n to a right-handed orthonormal basis (n, t1, t2).
  pure subroutine tangent_basis(n, t1, t2)
    real(dp), intent(in) :: n(3)
    real(dp), intent(out) :: t1(3), t2(3)
    ! Cross with the axis least aligned with n: no cancellation.
    if (abs(n(1)) <= abs(n(2)) .and. abs(n(1)) <= abs(n(3))) then
      t1 = [0.0_dp, n(3), -n(2)]
    else if (abs(n(2)) <= abs(n(3))) then
      t1 = [-n(3), 0.0_dp, n(1)]
    else
      t1 = [n(2), -n(1), 0.0_dp]
    end if
    t1 = t1/norm2(t1)
    t2 = cross(n, t1)
  end subroutine tangent_basis

  !> Solves for the impulses of contacts(:) (friction mu per contact in contacts%friction)
  !> and applies them to bodies%v, bodies%w. impulse(3, m): in, the warm start (world
  !> vectors); out, the impulses applied. Only the normal part is solved where `frictionless`.
  !> fixed_normal(m), when present, holds the normal impulses fixed (tangential solve only,
  !> with cone radius mu*fixed_normal): friction at an impact whose normal impulses are known.
  !> warm_applied: the warm start is already in the velocities (do not apply it again).
  subroutine solve_contacts_pgs(bodies, contacts, impulse, tolerance, max_sweeps, stats, fixed_normal, warm_applied, &
                                setup)
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    real(dp), intent(inout) :: impulse(:, :)
    real(dp), intent(in) :: tolerance      !< velocity change per sweep that ends the sweeps [m/s]
    integer, intent(in) :: max_sweeps
    type(pgs_stats_t), intent(inout) :: stats
    real(dp), intent(in), optional :: fixed_normal(:)
    logical, intent(in), optional :: warm_applied
    !> The contacts' geometry (bases, effective masses, responses), computed on the first call
    !> and reused while the bodies' poses and the contacts stay the same (the rounds of a
    !> staggered solve); the caller frees it when they change.
    type(pgs_setup_t), intent(inout), optional :: setup
    type(pgs_setup_t) :: own
    stats%solves = stats%solves + 1
    if (size(contacts) == 0) return
    if (present(setup)) then
      if (.not. setup%ready) call pgs_prepare(bodies, contacts, setup)
      call pgs_sweeps(bodies, contacts, impulse, tolerance, max_sweeps, stats, setup, fixed_normal, warm_applied)
    else
      call pgs_prepare(bodies, contacts, own)
      call pgs_sweeps(bodies, contacts, impulse, tolerance, max_sweeps, stats, own, fixed_normal, warm_applied)
    end if
  end subroutine solve_contacts_pgs

  !> The geometry of contacts(:) at the bodies' present poses (velocities not used).
  subroutine pgs_prepare(bodies, contacts, setup)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    type(pgs_setup_t), intent(inout) :: setup
    real(dp) :: k(3, 3)
    integer :: m, c
    m = size(contacts)
    call setup%free()
    allocate (setup%basis(3, 3, m), setup%k_tt(2, 2, m), setup%turn_a(3, 3, m), &
              setup%turn_b(3, 3, m), setup%arm_a(3, m), setup%arm_b(3, m), setup%inv_k_nn(m), setup%k_tn(2, m), &
              setup%inv_k_tt(2, 2, m), setup%eig_tt(2, m), setup%axis_tt(2, m))
    associate (basis => setup%basis)
      do c = 1, m
        setup%arm_a(:, c) = contacts(c)%point - bodies%x(:, contacts(c)%a)
        setup%arm_b(:, c) = contacts(c)%point - bodies%x(:, contacts(c)%b)
        basis(:, 1, c) = contacts(c)%normal
        call tangent_basis(contacts(c)%normal, basis(:, 2, c), basis(:, 3, c))
        ! Angular velocity change of each body per unit impulse along each basis direction
        ! (world I^-1 (r x d)), once per solve: the sweeps then turn no quaternions.
        call turn_responses(contacts(c)%a, c, setup%turn_a(:, :, c))
        call turn_responses(contacts(c)%b, c, setup%turn_b(:, :, c))
        k = effective_mass(bodies, contacts(c))
        setup%k_tt(:, :, c) = matmul(transpose(basis(:, 2:3, c)), matmul(k, basis(:, 2:3, c)))
        setup%inv_k_nn(c) = 1.0_dp/dot_product(basis(:, 1, c), matmul(k, basis(:, 1, c)))
        setup%k_tn(:, c) = matmul(transpose(basis(:, 2:3, c)), matmul(k, basis(:, 1, c)))
        call decompose2(setup%k_tt(:, :, c), setup%inv_k_tt(:, :, c), setup%eig_tt(:, c), setup%axis_tt(:, c))
      end do
    end associate
    ! The bodies of the group (moving ones), whose velocity changes per sweep end the loop:
    ! with more contact points than the impulses need (four corners of a face), impulses
    ! can drift between points while the velocities have long converged.
    call group_members(bodies, contacts, setup%members, setup%n_members, setup%side)
    ! reach: the farthest contact point of a body's contacts from its centre
    allocate (setup%reach(setup%n_members))
    setup%reach = 0.0_dp
    do c = 1, m
      if (setup%side(1, c) > 0) setup%reach(setup%side(1, c)) = max(setup%reach(setup%side(1, c)), &
                                                                     norm2(setup%arm_a(:, c)))
      if (setup%side(2, c) > 0) setup%reach(setup%side(2, c)) = max(setup%reach(setup%side(2, c)), &
                                                                     norm2(setup%arm_b(:, c)))
    end do
    setup%ready = .true.
  contains
    subroutine turn_responses(i, cc, turn)
      integer, intent(in) :: i, cc
      real(dp), intent(out) :: turn(3, 3)
      integer :: d
      turn = 0.0_dp
      if (bodies%fixed(i)) return
      do d = 1, 3
        turn(:, d) = world_inverse_inertia(bodies, i, cross(contacts(cc)%point - bodies%x(:, i), setup%basis(:, d, cc)))
      end do
    end subroutine turn_responses
  end subroutine pgs_prepare

  subroutine setup_free(self)
    class(pgs_setup_t), intent(inout) :: self
    if (allocated(self%basis)) deallocate (self%basis, self%k_tt, self%turn_a, self%turn_b, self%arm_a, &
                                           self%arm_b, self%inv_k_nn, self%k_tn, self%inv_k_tt, self%eig_tt, &
                                           self%axis_tt)
    if (allocated(self%members)) deallocate (self%members)
    if (allocated(self%side)) deallocate (self%side)
    if (allocated(self%reach)) deallocate (self%reach)
    self%n_members = 0
    self%ready = .false.
  end subroutine setup_free

  !> The warm start and the sweeps of solve_contacts_pgs over a prepared setup. Per contact
  !> and sweep: its relative velocity once, the normal step, the tangential velocity after
  !> it from the precomputed coupling k_tn (the impulse is linear in the velocities), the
  !> friction step, and one impulse on each body.
  subroutine pgs_sweeps(bodies, contacts, impulse, tolerance, max_sweeps, stats, setup, fixed_normal, warm_applied)
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    real(dp), intent(inout) :: impulse(:, :)
    real(dp), intent(in) :: tolerance
    integer, intent(in) :: max_sweeps
    type(pgs_stats_t), intent(inout) :: stats
    type(pgs_setup_t), intent(in) :: setup
    real(dp), intent(in), optional :: fixed_normal(:)
    logical, intent(in), optional :: warm_applied
    logical :: apply_warm, tangential_only
    real(dp), allocatable :: lam(:, :), v_prev(:, :), w_prev(:, :), nu_last(:)
    logical, allocatable :: moves_a(:), moves_b(:)
    real(dp) :: u(3), un, ut(2), dl(3), new_t(2), change, p(3), dw(3)
    integer :: m, c, b, sweep, ia, ib

    m = size(contacts)
    tangential_only = present(fixed_normal)
    apply_warm = .true.
    if (present(warm_applied)) apply_warm = .not. warm_applied
    allocate (lam(3, m), moves_a(m), moves_b(m), nu_last(m))
    nu_last = 0.0_dp
    associate (basis => setup%basis, k_tt => setup%k_tt, turn_a => setup%turn_a, turn_b => setup%turn_b, &
               arm_a => setup%arm_a, arm_b => setup%arm_b, members => setup%members, n_members => setup%n_members, &
               reach => setup%reach, inv_k_nn => setup%inv_k_nn, k_tn => setup%k_tn)
    do c = 1, m
      moves_a(c) = .not. bodies%fixed(contacts(c)%a)
      moves_b(c) = .not. bodies%fixed(contacts(c)%b)
      ! the warm start in the contact's basis, put inside the cone
      lam(:, c) = matmul(transpose(basis(:, :, c)), impulse(:, c))
      if (tangential_only) lam(1, c) = fixed_normal(c)
      lam(1, c) = max(lam(1, c), 0.0_dp)
      if (contacts(c)%friction <= 0.0_dp) lam(2:3, c) = 0.0_dp
      call clamp_to_cone(lam(2:3, c), contacts(c)%friction*lam(1, c))
      ! (with fixed normal impulses, those have been applied already by the caller)
      if (tangential_only) then
        p = matmul(basis(:, 2:3, c), lam(2:3, c))
      else
        p = matmul(basis(:, :, c), lam(:, c))
      end if
      if (apply_warm) call apply(bodies, contacts(c), p)
    end do

    allocate (v_prev(3, n_members), w_prev(3, n_members))
    do sweep = 1, max_sweeps
      do b = 1, n_members
        v_prev(:, b) = bodies%v(:, members(b))
        w_prev(:, b) = bodies%w(:, members(b))
      end do
      do c = 1, m
        ia = contacts(c)%a
        ib = contacts(c)%b
        u = bodies%v(:, ib) + cross(bodies%w(:, ib), arm_b(:, c)) - bodies%v(:, ia) - cross(bodies%w(:, ia), arm_a(:, c))
        dl = 0.0_dp
        if (.not. tangential_only) then
          un = basis(1, 1, c)*u(1) + basis(2, 1, c)*u(2) + basis(3, 1, c)*u(3)
          ! (a speculative contact may approach at up to its allowed speed)
          dl(1) = max(lam(1, c) - (un + contacts(c)%allowed_approach)*inv_k_nn(c), 0.0_dp) - lam(1, c)
          lam(1, c) = lam(1, c) + dl(1)
        end if
        if (contacts(c)%friction > 0.0_dp) then
          ut(1) = basis(1, 2, c)*u(1) + basis(2, 2, c)*u(2) + basis(3, 2, c)*u(3) + k_tn(1, c)*dl(1)
          ut(2) = basis(1, 3, c)*u(1) + basis(2, 3, c)*u(2) + basis(3, 3, c)*u(3) + k_tn(2, c)*dl(1)
          new_t = friction_step(k_tt(:, :, c), setup%inv_k_tt(:, :, c), setup%eig_tt(:, c), setup%axis_tt(:, c), &
                                lam(2:3, c), ut, contacts(c)%friction*lam(1, c), nu_last(c))
          dl(2:3) = new_t - lam(2:3, c)
          lam(2:3, c) = new_t
        end if
        if (dl(1) == 0.0_dp .and. dl(2) == 0.0_dp .and. dl(3) == 0.0_dp) cycle
        ! impulse basis dl on b, its opposite on a
        p = basis(:, 1, c)*dl(1) + basis(:, 2, c)*dl(2) + basis(:, 3, c)*dl(3)
        if (moves_b(c)) then
          dw = turn_b(:, 1, c)*dl(1) + turn_b(:, 2, c)*dl(2) + turn_b(:, 3, c)*dl(3)
          bodies%v(:, ib) = bodies%v(:, ib) + bodies%inv_mass(ib)*p
          bodies%w(:, ib) = bodies%w(:, ib) + dw
        end if
        if (moves_a(c)) then
          dw = turn_a(:, 1, c)*dl(1) + turn_a(:, 2, c)*dl(2) + turn_a(:, 3, c)*dl(3)
          bodies%v(:, ia) = bodies%v(:, ia) - bodies%inv_mass(ia)*p
          bodies%w(:, ia) = bodies%w(:, ia) - dw
        end if
      end do
      change = 0.0_dp
      do b = 1, n_members
        change = max(change, norm2(bodies%v(:, members(b)) - v_prev(:, b)) + &
                     norm2(bodies%w(:, members(b)) - w_prev(:, b))*reach(b))
      end do
      stats%sweeps = stats%sweeps + 1
      stats%max_sweeps_seen = max(stats%max_sweeps_seen, sweep)
      if (change <= tolerance) exit
      if (sweep == max_sweeps) stats%cap_hits = stats%cap_hits + 1
    end do
    do c = 1, m
      impulse(:, c) = matmul(basis(:, :, c), lam(:, c))
    end do
    end associate
  end subroutine pgs_sweeps

  !> New tangential impulse of one contact: minimises 1/2 x.K x + x.g over |x| <= limit,
  !> with g = u_t - K lambda_old (the energy change of the contact as a function of its
  !> new impulse x). Inside: x = -K^(-1) g. On the circle: x = -(K + nu I)^(-1) g with nu
  !> the root of |x(nu)| = limit, found by Newton on 1/|x(nu)| - 1/limit (convex and
  !> increasing in nu, so Newton from below converges monotonically; More and Sorensen), in
  !> K's eigenbasis (eig, axis: decompose2), where (K + nu I)^(-1) is diagonal.
  function friction_step(k, inv_k, eig, axis, lambda_old, ut, limit, nu_last) result(x)
    real(dp), intent(in) :: k(2, 2), inv_k(2, 2), eig(2), axis(2), lambda_old(2), ut(2), limit
    !> the shift nu of this contact's last sliding step (in), of this one (out): the Newton
    !> iteration starts there instead of at 0 (it converges from any start >= 0, at worst
    !> overshooting the root once; tests/unit/test_contact_solver starts it from 1e-2 to 1e2
    !> times the larger eigenvalue); in a converging solve a contact's shift changes little
    !> from sweep to sweep, so fewer iterations are left)
    real(dp), intent(inout), optional :: nu_last
    real(dp) :: x(2), g(2), gr(2), xr(2), d(2), phi, dphi, nu, size_x
    integer :: iteration
    g(1) = ut(1) - (k(1, 1)*lambda_old(1) + k(1, 2)*lambda_old(2))
    g(2) = ut(2) - (k(2, 1)*lambda_old(1) + k(2, 2)*lambda_old(2))
    x(1) = -(inv_k(1, 1)*g(1) + inv_k(1, 2)*g(2))
    x(2) = -(inv_k(2, 1)*g(1) + inv_k(2, 2)*g(2))
    if (x(1)**2 + x(2)**2 <= limit**2) return
    if (limit <= 0.0_dp .or. (g(1) == 0.0_dp .and. g(2) == 0.0_dp)) then
      x = 0.0_dp
      return
    end if
    ! g in the eigenbasis: components along (axis(1), axis(2)) and (-axis(2), axis(1))
    gr(1) = axis(1)*g(1) + axis(2)*g(2)
    gr(2) = -axis(2)*g(1) + axis(1)*g(2)
    nu = 0.0_dp
    if (present(nu_last)) nu = max(nu_last, 0.0_dp)
    do iteration = 1, 50
      d = eig + nu
      xr = -gr/d
      size_x = sqrt(xr(1)**2 + xr(2)**2)
      phi = 1.0_dp/size_x - 1.0_dp/limit
      if (abs(phi) <= 1.0e-14_dp/limit) exit
      ! d|x|/dnu = -x.(K + nu I)^(-1) x / |x|
      dphi = (xr(1)**2/d(1) + xr(2)**2/d(2))/size_x**3
      nu = max(nu - phi/dphi, 0.0_dp)
    end do
    if (present(nu_last)) nu_last = nu
    xr = xr*(limit/size_x)   ! on the circle to round-off
    x(1) = axis(1)*xr(1) - axis(2)*xr(2)
    x(2) = axis(2)*xr(1) + axis(1)*xr(2)
  end function friction_step

  !> A symmetric positive definite 2x2 k: its inverse, its eigenvalues (larger first) and
  !> the unit eigenvector of the larger one.
  pure subroutine decompose2(k, inv_k, eig, axis)
    real(dp), intent(in) :: k(2, 2)
    real(dp), intent(out) :: inv_k(2, 2), eig(2), axis(2)
    real(dp) :: det, q, angle
    q = 0.5_dp*(k(1, 2) + k(2, 1))
    det = k(1, 1)*k(2, 2) - q*q
    inv_k(1, 1) = k(2, 2)/det
    inv_k(2, 2) = k(1, 1)/det
    inv_k(1, 2) = -q/det
    inv_k(2, 1) = -q/det
    angle = 0.5_dp*atan2(2.0_dp*q, k(1, 1) - k(2, 2))
    axis = [cos(angle), sin(angle)]
    eig(1) = k(1, 1)*axis(1)**2 + 2.0_dp*q*axis(1)*axis(2) + k(2, 2)*axis(2)**2
    eig(2) = k(1, 1)*axis(2)**2 - 2.0_dp*q*axis(1)*axis(2) + k(2, 2)*axis(1)**2
  end subroutine decompose2

  pure subroutine clamp_to_cone(t, limit)
    real(dp), intent(inout) :: t(2)
    real(dp), intent(in) :: limit
    real(dp) :: size_t
    size_t = norm2(t)
    if (size_t > limit) then
      if (limit > 0.0_dp) then
        t = t*(limit/size_t)
      else
        t = 0.0_dp
      end if
    end if
  end subroutine clamp_to_cone

  !> The impulse p acts on b, -p on a (fixed bodies have zero inverse mass and inertia).
  pure subroutine apply(bodies, c, p)
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: c
    real(dp), intent(in) :: p(3)
    call kick(bodies, c%b, c%point, p)
    call kick(bodies, c%a, c%point, -p)
  end subroutine apply

  pure subroutine kick(bodies, i, point, p)
    type(bodies_t), intent(inout) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: point(3), p(3)
    if (bodies%fixed(i)) return
    bodies%v(:, i) = bodies%v(:, i) + bodies%inv_mass(i)*p
    bodies%w(:, i) = bodies%w(:, i) + world_inverse_inertia(bodies, i, cross(point - bodies%x(:, i), p))
  end subroutine kick

  pure function world_inverse_inertia(bodies, i, vector) result(r)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: vector(3)
    real(dp) :: r(3)
    r = quat_rotate(bodies%q(:, i), bodies%inv_inertia(:, i)*quat_rotate_inverse(bodies%q(:, i), vector))
  end function world_inverse_inertia

  !> K = (1/m_a + 1/m_b) I - [r_a]x I_a^-1 [r_a]x - [r_b]x I_b^-1 [r_b]x: the change of the
  !> relative contact velocity per unit impulse.
  pure function effective_mass(bodies, c) result(k)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: c
    real(dp) :: k(3, 3), e(3)
    integer :: axis
    do axis = 1, 3
      e = 0.0_dp
      e(axis) = 1.0_dp
      k(:, axis) = response(c%b, e) + response(c%a, e)
    end do
    k = 0.5_dp*(k + transpose(k))
  contains
    pure function response(i, p) result(du)
      integer, intent(in) :: i
      real(dp), intent(in) :: p(3)
      real(dp) :: du(3), r(3)
      du = 0.0_dp
      if (bodies%fixed(i)) return
      r = c%point - bodies%x(:, i)
      du = bodies%inv_mass(i)*p + cross(world_inverse_inertia(bodies, i, cross(r, p)), r)
    end function response
  end function effective_mass

end module contact_solver
