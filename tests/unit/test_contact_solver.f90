!> Projected Gauss-Seidel with Coulomb friction (contact/contact_solver): the per-contact
!> friction step against its optimality conditions on random anisotropic contacts (with a
!> negative control: scaling the stick impulse onto the circle fails them; and started from
!> a guessed shift, as the sweeps start it from the contact's last one), the 2x2 eigen
!> decomposition it uses, and whole solves with closed-form answers: a cube held at rest
!> on a floor by static friction, and a cube sliding on it (v_x drops by exactly mu g h, no
!> tipping, no bounce).
program test_contact_solver
  use kinds, only: dp
  use quaternion, only: quat_identity
  use random_stream, only: random_stream_t
  use body_state, only: bodies_t
  use impulse_solver, only: contact_t
  use contact_solver, only: pgs_stats_t, solve_contacts_pgs, friction_step, decompose2
  use assertions
  implicit none
  type(random_stream_t) :: rng
  type(bodies_t) :: bodies
  type(contact_t), allocatable :: contacts(:)
  type(pgs_stats_t) :: stats
  real(dp) :: k(2, 2), inv_k(2, 2), eig(2), axis(2), rot(2, 2), lambda_old(2), ut(2), limit, x(2), g(2), r(2)
  real(dp) :: angle, scale, worst_kkt, worst_cone, worst_sign, worst_sample, f_x, f_s, y(2), stick(2)
  real(dp), allocatable :: impulse(:, :)
  real(dp) :: nu_guess, x_warm(2), worst_warm
  integer :: trial, s, on_circle, control_fails
  real(dp), parameter :: h = 0.01_dp, g_acc = 9.81_dp, mu = 0.5_dp
  real(dp), parameter :: pi = acos(-1.0_dp)

  ! 1. friction_step on 4000 random contacts: K_tt = R diag(e1, e2) R^T with eigenvalues in
  !    [0.1, 10] (anisotropy up to 100, as at a box's corner), random old impulse, tangential
  !    velocity and cone radius. Optimality of min 1/2 x.K x + x.g over |x| <= limit: inside,
  !    K x + g = 0; on the circle, K x + g = -nu x with nu >= 0. Tolerances: 1e-10 of the
  !    problem's scale leaves ~1e5 ulps for the Newton iteration on the secular equation (it
  !    stops at 1e-14 relative on 1/|x|); the sampled objective (720 points on the circle)
  !    may not beat the step by more than round-off.
  call rng%init(17)
  worst_kkt = 0.0_dp
  worst_cone = 0.0_dp
  worst_sign = 0.0_dp
  worst_sample = 0.0_dp
  worst_warm = 0.0_dp
  on_circle = 0
  control_fails = 0
  do trial = 1, 4000
    angle = pi*rng%uniform()
    rot = reshape([cos(angle), sin(angle), -sin(angle), cos(angle)], [2, 2])
    eig = [10.0_dp**(2.0_dp*rng%uniform() - 1.0_dp), 10.0_dp**(2.0_dp*rng%uniform() - 1.0_dp)]
    k = matmul(rot, matmul(reshape([eig(1), 0.0_dp, 0.0_dp, eig(2)], [2, 2]), transpose(rot)))
    k = 0.5_dp*(k + transpose(k))
    call decompose2(k, inv_k, eig, axis)
    lambda_old = [rng%uniform() - 0.5_dp, rng%uniform() - 0.5_dp]
    ut = 4.0_dp*[rng%uniform() - 0.5_dp, rng%uniform() - 0.5_dp]
    limit = 2.0_dp*rng%uniform()
    x = friction_step(k, inv_k, eig, axis, lambda_old, ut, limit)
    ! started from another contact's shift (below or above the root, up to 100x the
    ! eigenvalues): the same step, to the Newton iteration's tolerance
    nu_guess = 10.0_dp**(4.0_dp*rng%uniform() - 2.0_dp)*eig(1)
    x_warm = friction_step(k, inv_k, eig, axis, lambda_old, ut, limit, nu_guess)
    worst_warm = max(worst_warm, norm2(x_warm - x)/max(limit, tiny(1.0_dp)))
    g = ut - matmul(k, lambda_old)
    scale = max(norm2(g), maxval(abs(k))*limit, tiny(1.0_dp))
    r = matmul(k, x) + g
    worst_cone = max(worst_cone, (norm2(x) - limit)/max(limit, tiny(1.0_dp)))
    if (norm2(x) < limit*(1.0_dp - 1.0e-9_dp)) then
      worst_kkt = max(worst_kkt, norm2(r)/scale)
    else
      on_circle = on_circle + 1
      ! r parallel to x, pointing against it
      worst_kkt = max(worst_kkt, abs(r(1)*x(2) - r(2)*x(1))/(scale*max(norm2(x), tiny(1.0_dp))))
      worst_sign = max(worst_sign, dot_product(r, x)/(scale*max(norm2(x), tiny(1.0_dp))))
      ! the stick impulse scaled onto the circle: optimal only where K_tt is isotropic
      stick = -matmul(inv_k, g)
      stick = stick*(limit/norm2(stick))
      if (objective(stick) > objective(x) + 1.0e-9_dp*scale*limit) control_fails = control_fails + 1
    end if
    f_x = objective(x)
    do s = 0, 719
      y = limit*[cos(2.0_dp*pi*s/720.0_dp), sin(2.0_dp*pi*s/720.0_dp)]
      f_s = objective(y)
      worst_sample = max(worst_sample, (f_x - f_s)/(scale*max(limit, 1.0e-3_dp)))
    end do
  end do
  call check(on_circle > 1000 .and. on_circle < 3900, 'friction step: both sticking and sliding cases drawn')
  call check_close(worst_cone, 0.0_dp, 0.0_dp, 'friction step: inside the cone', atol=1.0e-12_dp)
  call check_close(worst_kkt, 0.0_dp, 0.0_dp, 'friction step: optimality (stick: K x + g = 0; slide: parallel)', &
                   atol=1.0e-10_dp)
  call check(worst_sign <= 1.0e-12_dp, 'friction step: sliding friction opposes the slip (nu >= 0)')
  call check(worst_sample <= 1.0e-12_dp, 'friction step: no sampled point of the circle does better')
  call check(control_fails > 100, 'negative control: the stick impulse scaled onto the circle is not optimal')
  call check_close(worst_warm, 0.0_dp, 0.0_dp, 'friction step started from a guessed shift: the same step', &
                   atol=1.0e-10_dp)

  ! 2. decompose2: K rebuilt from its eigenpairs, and its inverse (round-off of O(1) entries).
  k = reshape([2.0_dp, 0.7_dp, 0.7_dp, 0.5_dp], [2, 2])
  call decompose2(k, inv_k, eig, axis)
  rot = reshape([axis(1), axis(2), -axis(2), axis(1)], [2, 2])
  call check_close_array(reshape(matmul(rot, matmul(reshape([eig(1), 0.0_dp, 0.0_dp, eig(2)], [2, 2]), &
                                                    transpose(rot))), [4]), reshape(k, [4]), 0.0_dp, &
                         'decompose2: K = R diag(eig) R^T', atol=1.0e-14_dp)
  call check_close_array(reshape(matmul(k, inv_k), [4]), [1.0_dp, 0.0_dp, 0.0_dp, 1.0_dp], 0.0_dp, &
                         'decompose2: K K^-1 = I', atol=1.0e-14_dp)
  call check(eig(1) >= eig(2), 'decompose2: larger eigenvalue first')

  ! 3. A unit cube (mass 1) resting on a fixed floor, four corner contacts, mu = 0.5, after
  !    gravity's impulse of a step (v_z = -g h) and a slow sideways drift (0.02 m/s, inside
  !    the cone): static friction holds it, the cube ends at rest. Converged to 1e-13 m/s per
  !    sweep, so 1e-10 m/s is the PGS tolerance with margin for its geometric tail.
  call make_cube_on_floor(bodies, contacts, [0.02_dp, 0.0_dp, -g_acc*h])
  allocate (impulse(3, 4))
  impulse = 0.0_dp
  call solve_contacts_pgs(bodies, contacts, impulse, 1.0e-13_dp, 10000, stats)
  call check(stats%cap_hits == 0, 'cube at rest: PGS converged')
  call check_close(norm2(bodies%v(:, 2)), 0.0_dp, 0.0_dp, 'cube at rest: no velocity left', atol=1.0e-10_dp)
  call check_close(norm2(bodies%w(:, 2)), 0.0_dp, 0.0_dp, 'cube at rest: no spin', atol=1.0e-10_dp)
  call check_close(sum(impulse(3, :)), g_acc*h, 0.0_dp, 'cube at rest: normal impulses carry m g h', &
                   atol=1.0e-10_dp)
  call check(all(norm2(impulse(1:2, :), dim=1) <= mu*impulse(3, :)*(1.0_dp + 1.0e-12_dp)), &
             'cube at rest: every impulse inside its cone')

  ! 4. The same cube sliding at 1 m/s: all four corners slide the same way, so the friction
  !    impulse is mu times the normal one, v_x = 1 - mu g h exactly; the tipping moment of
  !    friction is carried by the front corners' larger normal impulses (mu h_half = 0.25 <
  !    half the width), so no spin and no bounce.
  call make_cube_on_floor(bodies, contacts, [1.0_dp, 0.0_dp, -g_acc*h])
  impulse = 0.0_dp
  stats = pgs_stats_t()
  call solve_contacts_pgs(bodies, contacts, impulse, 1.0e-13_dp, 10000, stats)
  call check(stats%cap_hits == 0, 'sliding cube: PGS converged')
  call check_close(bodies%v(1, 2), 1.0_dp - mu*g_acc*h, 0.0_dp, 'sliding cube: v_x drops by mu g h', atol=1.0e-10_dp)
  call check_close(bodies%v(3, 2), 0.0_dp, 0.0_dp, 'sliding cube: no bounce, no sinking', atol=1.0e-10_dp)
  call check_close(norm2(bodies%w(:, 2)), 0.0_dp, 0.0_dp, 'sliding cube: no tipping', atol=1.0e-10_dp)
  call check(impulse(3, 1) > impulse(3, 2) .or. impulse(3, 4) > impulse(3, 3), &
             'sliding cube: the front corners carry more')

  call test_finish()

contains

  !> 1/2 y.K y + y.g: the contact's energy change as a function of its tangential impulse.
  real(dp) function objective(yy)
    real(dp), intent(in) :: yy(2)
    objective = 0.5_dp*dot_product(yy, matmul(k, yy)) + dot_product(yy, g)
  end function objective

  !> Body 1: fixed floor; body 2: unit cube (mass 1, I = 1/6) standing on it at z = 0.5 with
  !> velocity v; contacts at the four bottom corners, normal +z.
  subroutine make_cube_on_floor(b, c, v)
    type(bodies_t), intent(inout) :: b
    type(contact_t), allocatable, intent(out) :: c(:)
    real(dp), intent(in) :: v(3)
    integer :: corner
    real(dp), parameter :: corners(2, 4) = reshape([0.5_dp, 0.5_dp, -0.5_dp, 0.5_dp, -0.5_dp, -0.5_dp, &
                                                    0.5_dp, -0.5_dp], [2, 4])
    call b%free()
    call b%allocate(2)
    b%n_owned = 2
    b%fixed(1) = .true.
    b%x(:, 1) = [0.0_dp, 0.0_dp, -1.0_dp]
    b%q(:, 1) = quat_identity
    b%mass(2) = 1.0_dp
    b%inv_mass(2) = 1.0_dp
    b%inertia(:, 2) = 1.0_dp/6.0_dp
    b%inv_inertia(:, 2) = 6.0_dp
    b%x(:, 2) = [0.0_dp, 0.0_dp, 0.5_dp]
    b%q(:, 2) = quat_identity
    b%v(:, 2) = v
    b%w(:, 2) = 0.0_dp
    allocate (c(4))
    do corner = 1, 4
      c(corner) = contact_t(a=1, b=2, point=[corners(1, corner), corners(2, corner), 0.0_dp], &
                            normal=[0.0_dp, 0.0_dp, 1.0_dp], friction=mu)
    end do
  end subroutine make_cube_on_floor

end program test_contact_solver
