!> Simultaneous frictionless impulses: analytic two-body results, a box landing flat (no
!> spurious spin), Newton's cradle (only the last ball leaves), and on random contact sets
!> the invariants: momentum conserved, no energy gained (kept at e = 1), nothing approaching;
!> speculative contacts (an allowed approach speed): the projection's KKT conditions; contact
!> groups and the local numbering of their bodies; groups whose contacts have different e
!> (each contact's own e, invariants kept); normal_curvature against second differences of
!> the gap under the exact torque-free motion.
program test_impulse_solver
  use kinds, only: dp
  use error_status, only: error_t
  use quaternion, only: quat_exp, quat_identity
  use random_stream, only: random_stream_t
  use body_state, only: bodies_t
  use free_rotation_exact, only: exact_rotate
  use quaternion, only: quat_rotate, quat_rotate_inverse
  use vector_ops, only: cross
  use impulse_solver
  use assertions
  implicit none
  type(bodies_t) :: bodies
  type(contact_t), allocatable :: contacts(:)
  type(impulse_stats_t) :: stats
  type(error_t) :: err
  integer :: i, trial, violations(4)
  real(dp) :: e, ke0, ke1, p0(3), p1(3)
  real(dp), allocatable :: impulse(:)
  type(random_stream_t) :: rng
  ! Tolerances: every result below is a few flops of exact arithmetic away from its
  ! closed form, so 1e-12 absolute on O(1) velocities leaves ~1e3 ulps for the QR solves.
  real(dp), parameter :: tol = 1.0e-12_dp

  ! 1. Head-on equal spheres (mass 1, radius 0.5, touching at x = 0.5), e = 1 and 0.5.
  do i = 1, 2
    e = merge(1.0_dp, 0.5_dp, i == 1)
    call make_spheres(bodies, 2)
    bodies%x(:, 2) = [1.0_dp, 0.0_dp, 0.0_dp]
    bodies%v(:, 1) = [1.0_dp, 0.0_dp, 0.0_dp]
    contacts = [contact_t(a=1, b=2, point=[0.5_dp, 0.0_dp, 0.0_dp], normal=[1.0_dp, 0.0_dp, 0.0_dp], restitution=e)]
    call resolve_impacts(bodies, contacts, 1.0e-9_dp, 20, stats, err)
    ! v1' = (1 - e)/2, v2' = (1 + e)/2 for equal masses, v1 = 1, v2 = 0.
    call check_close(bodies%v(1, 1), (1.0_dp - e)/2.0_dp, 0.0_dp, 'head-on: v1 after', atol=tol)
    call check_close(bodies%v(1, 2), (1.0_dp + e)/2.0_dp, 0.0_dp, 'head-on: v2 after', atol=tol)
  end do

  ! 2. Unit cube (mass 1, I = 1/6) landing flat on a fixed floor at v_z = -2: four corner
  !    contacts, rank-3 contact matrix. e = 1 -> v_z = +2, e = 0.5 -> v_z = +1; no spin.
  do i = 1, 2
    e = merge(1.0_dp, 0.5_dp, i == 1)
    call make_cube_on_floor(bodies, contacts, e)
    call resolve_impacts(bodies, contacts, 1.0e-9_dp, 20, stats, err)
    call check(err%ok(), 'cube landing: solver succeeded')
    call check_close(bodies%v(3, 2), 2.0_dp*e, 0.0_dp, 'cube landing flat: bounces at e v', atol=tol)
    call check_close(norm2(bodies%w(:, 2)), 0.0_dp, 0.0_dp, 'cube landing flat: no spin', atol=tol)
    call check_close(norm2(bodies%v(1:2, 2)), 0.0_dp, 0.0_dp, 'cube landing flat: no drift', atol=tol)
  end do

  ! 3. Newton's cradle: 5 touching balls, e = 1, the first moving at 1 m/s: only the last
  !    one moves afterwards (to 1e-8, the issue's tolerance; we get round-off).
  call make_spheres(bodies, 5)
  contacts = [(contact_t(a=i, b=i + 1, point=[i - 0.5_dp, 0.0_dp, 0.0_dp], normal=[1.0_dp, 0.0_dp, 0.0_dp], &
                         restitution=1.0_dp), i=1, 4)]
  do i = 1, 5
    bodies%x(:, i) = [real(i - 1, dp), 0.0_dp, 0.0_dp]
  end do
  bodies%v(:, 1) = [1.0_dp, 0.0_dp, 0.0_dp]
  call resolve_impacts(bodies, contacts, 1.0e-9_dp, 50, stats, err)
  call check_close_array(bodies%v(1, :), [0.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp], 0.0_dp, &
                         "Newton's cradle: only the last ball moves", atol=1.0e-8_dp)
  ! Two balls launched into three: the last two leave at 1 m/s.
  call make_spheres(bodies, 5)
  do i = 1, 5
    bodies%x(:, i) = [real(i - 1, dp), 0.0_dp, 0.0_dp]
  end do
  bodies%v(:, 1) = [1.0_dp, 0.0_dp, 0.0_dp]
  bodies%v(:, 2) = [1.0_dp, 0.0_dp, 0.0_dp]
  call resolve_impacts(bodies, contacts, 1.0e-9_dp, 50, stats, err)
  call check_close_array(bodies%v(1, :), [0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 1.0_dp], 0.0_dp, &
                         "cradle, two into three: the last two leave", atol=1.0e-8_dp)

  ! 4. Random contact sets among 6 spinning boxes and a fixed body: invariants, counted
  !    over 200 scenes. Momentum is only conserved when no contact touches the fixed body.
  call rng%init(3)
  violations = 0
  do trial = 1, 200
    e = merge(1.0_dp, rng%uniform(), mod(trial, 2) == 0)
    call make_random_scene(rng, bodies, contacts, e)
    call totals(bodies, ke0, p0)
    call resolve_impacts(bodies, contacts, 1.0e-9_dp, 100, stats, err)
    if (err%failed()) exit
    call totals(bodies, ke1, p1)
    if (all(contacts%a /= 7 .and. contacts%b /= 7) .and. norm2(p1 - p0) > 1.0e-12_dp*max(1.0_dp, norm2(p0))) &
      violations(1) = violations(1) + 1
    if (ke1 > ke0*(1.0_dp + 1.0e-12_dp)) violations(2) = violations(2) + 1
    if (e == 1.0_dp .and. abs(ke1 - ke0) > 1.0e-10_dp*ke0) violations(3) = violations(3) + 1
    if (minval([(normal_velocity(bodies, contacts(i)), i=1, size(contacts))]) < -1.0e-9_dp) &
      violations(4) = violations(4) + 1
  end do
  call check(err%ok(), 'random scenes: solver never failed')
  call check(violations(1) == 0, 'random scenes: momentum conserved (without the fixed body)')
  call check(violations(2) == 0, 'random scenes: no energy gained')
  call check(violations(3) == 0, 'random scenes, e = 1: energy kept to 1e-10')
  call check(violations(4) == 0, 'random scenes: no contact approaches afterwards')
  call check(stats%cap_hits == 0, 'random scenes: reflection loop never hit its cap')

  ! 5. Speculative contacts (the contact pass): a contact may approach at up to its allowed
  !    speed. A cube falling flat at 2 m/s onto a floor it may approach at 0.5 m/s keeps
  !    exactly 0.5 m/s (the projection onto u >= -0.5: the appended eps rows shift the answer
  !    by eps^2 = 1e-10 of the velocity change, so 1e-9 absolute), with no spin; one allowed
  !    3 m/s is not touched at all.
  call make_cube_on_floor(bodies, contacts, 0.0_dp)
  contacts%allowed_approach = 0.5_dp
  call resolve_impacts(bodies, contacts, 1.0e-9_dp, 20, stats, err)
  call check(err%ok(), 'speculative landing: solver succeeded')
  call check_close(bodies%v(3, 2), -0.5_dp, 0.0_dp, 'speculative landing: approaches at the allowed speed', atol=1.0e-9_dp)
  call check_close(norm2(bodies%w(:, 2)), 0.0_dp, 0.0_dp, 'speculative landing: no spin', atol=1.0e-9_dp)
  call make_cube_on_floor(bodies, contacts, 0.0_dp)
  contacts%allowed_approach = 3.0_dp
  call resolve_impacts(bodies, contacts, 1.0e-9_dp, 20, stats, err)
  call check(bodies%v(3, 2) == -2.0_dp .and. all(bodies%w(:, 2) == 0.0_dp), 'speculative, slow enough: untouched')
  ! Random inelastic scenes with random allowed speeds: the KKT conditions of the projection
  ! (every contact at or above its bound, the loaded ones on it) and no energy gained.
  call rng%init(5)
  violations = 0
  do trial = 1, 200
    call make_random_scene(rng, bodies, contacts, 0.0_dp)
    do i = 1, size(contacts)
      contacts(i)%allowed_approach = merge(0.0_dp, 0.5_dp*rng%uniform(), mod(i, 3) == 0)
    end do
    call totals(bodies, ke0, p0)
    allocate (impulse(size(contacts)))
    call resolve_impacts(bodies, contacts, 1.0e-9_dp, 100, stats, err, impulse)
    if (err%failed()) exit
    call totals(bodies, ke1, p1)
    if (ke1 > ke0*(1.0_dp + 1.0e-12_dp)) violations(1) = violations(1) + 1
    do i = 1, size(contacts)
      if (normal_velocity(bodies, contacts(i)) < -contacts(i)%allowed_approach - 1.0e-8_dp) violations(2) = violations(2) + 1
      if (impulse(i) > 1.0e-9_dp .and. abs(normal_velocity(bodies, contacts(i)) + contacts(i)%allowed_approach) > 1.0e-8_dp) &
        violations(3) = violations(3) + 1
      if (impulse(i) < 0.0_dp) violations(4) = violations(4) + 1
    end do
    deallocate (impulse)
  end do
  call check(err%ok(), 'speculative scenes: solver never failed')
  call check(violations(1) == 0, 'speculative scenes: no energy gained')
  call check(violations(2) == 0, 'speculative scenes: no contact approaches faster than allowed')
  call check(violations(3) == 0, 'speculative scenes: loaded contacts sit on their bound (complementarity)')
  call check(violations(4) == 0, 'speculative scenes: impulses push, never pull')

  ! 7. One group, two materials: ball 3 at rest (mass 1) hit at once by ball 1 along +x at
  !    1 m/s through a contact of e = 0.9 and by ball 2 along +y at 1 m/s through one of
  !    e = 0.5. The normals are orthogonal and pass through the centres, so the two contacts
  !    do not couple (K is diagonal) and each must give the 1D equal-mass result of its own e:
  !    v1' = (1 - e1)/2, v3x' = (1 + e1)/2, v2' = (1 - e2)/2, v3y' = (1 + e2)/2 (a single
  !    group e, the smallest, would give 0.75 to both). Same closed-form tolerance as 1.
  call make_spheres(bodies, 3)
  bodies%x(:, 1) = [-1.0_dp, 0.0_dp, 0.0_dp]
  bodies%x(:, 2) = [0.0_dp, -1.0_dp, 0.0_dp]
  bodies%v(:, 1) = [1.0_dp, 0.0_dp, 0.0_dp]
  bodies%v(:, 2) = [0.0_dp, 1.0_dp, 0.0_dp]
  contacts = [contact_t(a=1, b=3, point=[-0.5_dp, 0.0_dp, 0.0_dp], normal=[1.0_dp, 0.0_dp, 0.0_dp], restitution=0.9_dp), &
              contact_t(a=2, b=3, point=[0.0_dp, -0.5_dp, 0.0_dp], normal=[0.0_dp, 1.0_dp, 0.0_dp], restitution=0.5_dp)]
  call resolve_impacts(bodies, contacts, 1.0e-9_dp, 20, stats, err)
  call check(err%ok(), 'two materials: solver succeeded')
  call check_close(bodies%v(1, 1), 0.05_dp, 0.0_dp, 'two materials: ball of e = 0.9 after', atol=tol)
  call check_close(bodies%v(2, 2), 0.25_dp, 0.0_dp, 'two materials: ball of e = 0.5 after', atol=tol)
  call check_close(bodies%v(1, 3), 0.95_dp, 0.0_dp, 'two materials: struck ball, x (e = 0.9)', atol=tol)
  call check_close(bodies%v(2, 3), 0.75_dp, 0.0_dp, 'two materials: struck ball, y (e = 0.5)', atol=tol)

  ! 8. Random scenes whose contacts have random e in [0, 1]: the per-contact blend (or its
  !    fallback) keeps momentum (when no fixed body is touched), never gains energy, and
  !    leaves nothing approaching; tolerances as in 4.
  violations = 0
  stats = impulse_stats_t()
  do trial = 1, 300
    call make_random_scene(rng, bodies, contacts, 0.0_dp)
    do i = 1, size(contacts)
      contacts(i)%restitution = rng%uniform()
    end do
    call totals(bodies, ke0, p0)
    call resolve_impacts(bodies, contacts, 1.0e-9_dp, 100, stats, err)
    if (err%failed()) exit
    call totals(bodies, ke1, p1)
    if (ke1 > ke0*(1.0_dp + 1.0e-12_dp)) violations(1) = violations(1) + 1
    if (all(contacts%a /= 7 .and. contacts%b /= 7) .and. norm2(p1 - p0) > 1.0e-12_dp*max(1.0_dp, norm2(p0))) &
      violations(2) = violations(2) + 1
    do i = 1, size(contacts)
      if (normal_velocity(bodies, contacts(i)) < -1.0e-9_dp) violations(3) = violations(3) + 1
    end do
  end do
  call check(err%ok(), 'mixed-e scenes: solver never failed')
  call check(violations(1) == 0, 'mixed-e scenes: no energy gained')
  call check(violations(2) == 0, 'mixed-e scenes: momentum conserved')
  call check(violations(3) == 0, 'mixed-e scenes: nothing approaches')
  print '(a, i0, a, i0)', 'mixed-e scenes: groups with their own e ', stats%mixed_groups, ', fell back ', &
    stats%mixed_fallbacks
  call check(stats%mixed_groups > stats%mixed_fallbacks, 'mixed-e scenes: most groups keep each contact''s e')

  ! 6. Contact groups and the local numbering of their bodies (contact_groups, group_members):
  !    bodies 1 and 8 fixed; contacts 2-3, 1-4, 5-2, 1-8 (fixed-fixed: no group), 6-7, 3-5,
  !    4-1: groups {1, 3, 6} (bodies 2, 3, 5), {2, 7} (body 4), {5} (bodies 6, 7), in the
  !    order of their first contact, contacts in increasing index.
  call make_spheres(bodies, 8)
  bodies%fixed([1, 8]) = .true.
  block
    integer, allocatable :: group_start(:), group_list(:), members(:), side(:, :)
    integer :: n_groups, n_members
    integer, parameter :: pairs(2, 7) = reshape([2, 3, 1, 4, 5, 2, 1, 8, 6, 7, 3, 5, 4, 1], [2, 7])
    if (allocated(contacts)) deallocate (contacts)
    allocate (contacts(7))
    contacts%a = pairs(1, :)
    contacts%b = pairs(2, :)
    call contact_groups(bodies, contacts, group_start, group_list, n_groups)
    call check(n_groups == 3, 'contact groups: three groups (the fixed-fixed contact in none)')
    if (n_groups == 3) then
      call check(all(group_start == [1, 4, 6, 7]), 'contact groups: sizes 3, 2, 1')
      call check(all(group_list == [1, 3, 6, 2, 7, 5]), 'contact groups: by first contact, contacts in order')
    end if
    call group_members(bodies, contacts, members, n_members, side)
    call check(n_members == 6, 'group members: six moving bodies')
    call check(all(members(1:n_members) == [2, 3, 4, 5, 6, 7]), 'group members: in order of first appearance')
    call check(all(side(1, :) == [1, 0, 4, 0, 5, 2, 3]) .and. all(side(2, :) == [2, 3, 1, 0, 6, 4, 0]), &
               'group members: each contact side numbered, fixed bodies 0')
    ! first appearance, not body order: contact 5-2 alone numbers 5 first
    call group_members(bodies, contacts(3:3), members, n_members, side)
    call check(n_members == 2 .and. all(members(1:2) == [5, 2]) .and. all(side(:, 1) == [1, 2]), &
               'group members: the first side seen comes first')
  end block
  ! 9. normal_curvature (the contact pass's turning term): the gap's second time derivative
  !    at t = 0 under the real motion (translation at constant velocity, exact torque-free
  !    rotation of triaxial bodies, |w| up to 5 rad/s), with the normal carried by body a or
  !    by body b; the function gives the smaller of the two. Reference: the five-point second
  !    difference over tau = 1e-3 s of g(t) = n(t).(p_b(t) - p_a(t)) for the material points
  !    at the contact (g(0) = 0): truncation ~tau^4 |g^(6)|/90 ~ 3e-8 (w^6 r with r ~ 2 m),
  !    round-off ~64 ulp(2 m)/(12 tau^2) ~ 2e-9, hence 1e-6 absolute. Negative control: without the normal's turning term
  !    (centripetal and Euler terms only) the second differences differ by more than 1e-2
  !    somewhere, so the test sees the term that caused the pile's micro-impacts.
  call rng%init(11)
  block
    real(dp) :: fd(2), expected, worst, no_coriolis_gap
    integer :: carrier
    worst = 0.0_dp
    no_coriolis_gap = 0.0_dp
    do trial = 1, 200
      call make_random_scene(rng, bodies, contacts, 0.0_dp)
      bodies%w(:, 1:6) = 3.0_dp*bodies%w(:, 1:6)
      do i = 1, size(contacts)
        do carrier = 1, 2
          fd(carrier) = gap_second_difference(bodies, contacts(i), carrier, 1.0e-3_dp)
        end do
        expected = minval(fd)   ! (a fixed body's normal does not turn: its fd is the other term)
        worst = max(worst, abs(normal_curvature(bodies, contacts(i)) - expected))
        no_coriolis_gap = max(no_coriolis_gap, abs(centripetal_only(bodies, contacts(i)) - expected))
      end do
    end do
    call check_close(worst, 0.0_dp, 0.0_dp, 'normal curvature: second differences of the gap, 200 scenes', atol=1.0e-6_dp)
    call check(no_coriolis_gap > 1.0e-2_dp, 'normal curvature: without the turning normal the test would fail')
  end block
  call test_finish()

contains
  !> Five-point second difference of contact c's gap over tau, the normal turning with body a
  !> (carrier 1) or b (2), the material points of both bodies at c%point followed exactly.
  real(dp) function gap_second_difference(b, c, carrier, tau) result(d2)
    type(bodies_t), intent(in) :: b
    type(contact_t), intent(in) :: c
    integer, intent(in) :: carrier
    real(dp), intent(in) :: tau
    real(dp) :: g(-2:2), pa(3), pb(3), n(3)
    integer :: s
    do s = -2, 2
      pa = material_point(b, c%a, c%point, s*tau)
      pb = material_point(b, c%b, c%point, s*tau)
      if (carrier == 1) then
        n = carried(b, c%a, c%normal, s*tau)
      else
        n = carried(b, c%b, c%normal, s*tau)
      end if
      g(s) = dot_product(n, pb - pa)
    end do
    d2 = (-g(2) + 16.0_dp*g(1) - 30.0_dp*g(0) + 16.0_dp*g(-1) - g(-2))/(12.0_dp*tau**2)
  end function gap_second_difference

  !> Where body k's material point at p (at t = 0) is at time t [m].
  function material_point(b, k, p, t) result(x)
    type(bodies_t), intent(in) :: b
    integer, intent(in) :: k
    real(dp), intent(in) :: p(3), t
    real(dp) :: x(3)
    x = b%x(:, k) + b%v(:, k)*t + carried(b, k, p - b%x(:, k), t)
  end function material_point

  !> Direction d (at t = 0) carried by body k's exact torque-free rotation to time t.
  function carried(b, k, d, t) result(dt)
    type(bodies_t), intent(in) :: b
    integer, intent(in) :: k
    real(dp), intent(in) :: d(3), t
    real(dp) :: dt(3), q(4), w(3)
    if (b%fixed(k)) then
      dt = d
      return
    end if
    q = b%q(:, k)
    w = b%w(:, k)
    call exact_rotate(q, w, b%inertia(:, k), t)
    dt = quat_rotate(q, quat_rotate_inverse(b%q(:, k), d))
  end function carried

  !> The curvature without the normal's turning: n.(a_b - a_a) from the material points'
  !> accelerations alone (w x (w x r) + alpha x r), for the negative control.
  real(dp) function centripetal_only(b, c) result(cc)
    type(bodies_t), intent(in) :: b
    type(contact_t), intent(in) :: c
    cc = dot_product(c%normal, body_accel(b, c%b, c%point) - body_accel(b, c%a, c%point))
  end function centripetal_only

  function body_accel(b, k, p) result(acc)
    type(bodies_t), intent(in) :: b
    integer, intent(in) :: k
    real(dp), intent(in) :: p(3)
    real(dp) :: acc(3), r(3), wb(3), alpha(3)
    acc = 0.0_dp
    if (b%fixed(k)) return
    r = p - b%x(:, k)
    wb = quat_rotate_inverse(b%q(:, k), b%w(:, k))
    alpha = quat_rotate(b%q(:, k), cross(b%inertia(:, k)*wb, wb)/b%inertia(:, k))
    acc = cross(b%w(:, k), cross(b%w(:, k), r)) + cross(alpha, r)
  end function body_accel


  !> n unit spheres (mass 1, radius 0.5) at rest at the origin.
  subroutine make_spheres(b, n)
    type(bodies_t), intent(inout) :: b
    integer, intent(in) :: n
    call b%allocate(n)
    b%n_owned = n
    b%mass = 1.0_dp
    b%inv_mass = 1.0_dp
    b%inertia = 0.1_dp
    b%inv_inertia = 10.0_dp
  end subroutine make_spheres

  subroutine make_cube_on_floor(b, c, e)
    type(bodies_t), intent(inout) :: b
    type(contact_t), allocatable, intent(out) :: c(:)
    real(dp), intent(in) :: e
    integer :: k
    real(dp), parameter :: corners(2, 4) = reshape([0.5_dp, 0.5_dp, -0.5_dp, 0.5_dp, -0.5_dp, -0.5_dp, &
                                                    0.5_dp, -0.5_dp], [2, 4])
    call b%allocate(2)
    b%n_owned = 2
    b%fixed(1) = .true.
    b%x(:, 1) = [0.0_dp, 0.0_dp, -1.0_dp]
    b%mass(2) = 1.0_dp
    b%inv_mass(2) = 1.0_dp
    b%inertia(:, 2) = 1.0_dp/6.0_dp
    b%inv_inertia(:, 2) = 6.0_dp
    b%x(:, 2) = [0.0_dp, 0.0_dp, 0.5_dp]
    b%q(:, 2) = quat_identity
    b%v(:, 2) = [0.0_dp, 0.0_dp, -2.0_dp]
    allocate (c(4))
    do k = 1, 4
      c(k) = contact_t(a=1, b=2, point=[corners(1, k), corners(2, k), 0.0_dp], normal=[0.0_dp, 0.0_dp, 1.0_dp], &
                       restitution=e)
    end do
  end subroutine make_cube_on_floor

  !> Six boxes with random masses, inertias, orientations and velocities, and 1-10 random
  !> contacts between random pairs (or with a fixed body 7).
  subroutine make_random_scene(rng, b, c, e)
    type(random_stream_t), intent(inout) :: rng
    type(bodies_t), intent(inout) :: b
    type(contact_t), allocatable, intent(out) :: c(:)
    real(dp), intent(in) :: e
    integer :: k, n_contacts, ia, ib
    call b%allocate(7)
    b%n_owned = 7
    do k = 1, 6
      b%mass(k) = 0.5_dp + rng%uniform()
      b%inv_mass(k) = 1.0_dp/b%mass(k)
      b%inertia(:, k) = [0.2_dp + rng%uniform(), 0.2_dp + rng%uniform(), 0.2_dp + rng%uniform()]
      b%inv_inertia(:, k) = 1.0_dp/b%inertia(:, k)
      b%x(:, k) = [rng%symmetric(2.0_dp), rng%symmetric(2.0_dp), rng%symmetric(2.0_dp)]
      b%q(:, k) = quat_exp([rng%symmetric(3.0_dp), rng%symmetric(3.0_dp), rng%symmetric(3.0_dp)])
      b%v(:, k) = [rng%symmetric(1.0_dp), rng%symmetric(1.0_dp), rng%symmetric(1.0_dp)]
      b%w(:, k) = [rng%symmetric(1.0_dp), rng%symmetric(1.0_dp), rng%symmetric(1.0_dp)]
    end do
    b%fixed(7) = .true.
    n_contacts = 1 + int(10*rng%uniform())
    allocate (c(n_contacts))
    do k = 1, n_contacts
      ia = 1 + int(7*rng%uniform())
      ib = 1 + int(6*rng%uniform())
      if (ib >= ia) ib = ib + 1
      c(k)%a = ia
      c(k)%b = ib
      c(k)%point = 0.5_dp*(b%x(:, ia) + b%x(:, ib)) + [rng%symmetric(0.3_dp), rng%symmetric(0.3_dp), 0.0_dp]
      c(k)%normal = rng%unit_vector()
      c(k)%restitution = e
    end do
  end subroutine make_random_scene

  subroutine totals(b, ke, p)
    type(bodies_t), intent(in) :: b
    real(dp), intent(out) :: ke, p(3)
    real(dp) :: et, er
    integer :: k
    ke = 0.0_dp
    p = 0.0_dp
    do k = 1, b%n_owned
      if (b%fixed(k)) cycle
      call b%kinetic_energy(k, et, er)
      ke = ke + et + er
      p = p + b%mass(k)*b%v(:, k)
    end do
  end subroutine totals

end program test_impulse_solver
