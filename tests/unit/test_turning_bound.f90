!> The directional bound for turning bodies (turning_bound) must never be exceeded by the
!> real torque-free motion (the exact rotor the propagator uses), and must be sharp enough
!> that a bound 10% too tight is caught by the same samples.
!> 1. One body: the rise of its highest point along a fixed n over [0, tau] against the
!>    bound max_k (c_k + s_k tau) + K tau^2/2, for random vertex sets, principal moments
!>    (isotropic, axisymmetric, triaxial), orientations, spins and intervals up to 3 rad
!>    of turning; the same samples with the bound times 0.9 must find a violation.
!> 2. Two bodies on parabolas, turning: before directional_time the separation along n
!>    never falls below `above`; and at that time some samples close nearly the whole room
!>    (so an answer 10% later in closing would have been caught).
program test_turning_bound
  use kinds, only: dp
  use quaternion, only: quat_exp, quat_rotate
  use random_stream, only: random_stream_t
  use free_rotation_exact, only: free_rotor_t
  use turning_bound
  use assertions
  implicit none
  type(random_stream_t) :: rng
  integer, parameter :: n_trials = 400, n_times = 60, max_nodes = 12
  real(dp) :: worst, worst_tight, worst_closing
  integer :: trial, violations, violations_tight, violations_pair

  call rng%init(20261204)
  worst = 0.0_dp
  worst_tight = 0.0_dp
  violations = 0
  violations_tight = 0
  do trial = 1, n_trials
    call one_body_trial(trial, worst, violations, 1.0_dp)
  end do
  call rng%init(20261204)
  do trial = 1, n_trials
    call one_body_trial(trial, worst_tight, violations_tight, 0.9_dp)
  end do
  print '(a, es12.4, a, i0)', 'one body: worst rise / bound ', worst, ', violations ', violations
  print '(a, es12.4, a, i0)', 'one body, bound x 0.9: worst rise / bound ', worst_tight, ', violations ', &
    violations_tight
  call check(violations == 0, 'rise of the highest point along n never exceeds the bound')
  call check(violations_tight > 0, 'the same samples catch a bound 10% too tight')

  call rng%init(77)
  violations_pair = 0
  worst_closing = 0.0_dp
  do trial = 1, n_trials
    call pair_trial(violations_pair, worst_closing)
  end do
  print '(a, i0, a, f8.5)', 'pairs: violations ', violations_pair, ', largest closing / room at the answer ', &
    worst_closing
  call check(violations_pair == 0, 'separation along n stays above `above` until directional_time')
  call check(worst_closing > 0.9_dp, 'some pair closes more than 90% of the room by then (the test is sharp)')
  ! The supporting vertex alone counts at first order: a cube face-on, spinning about n,
  ! has no first-order closing at all, so the answer is second order (Omega R t^2/2 = room).
  call check_spin_about_normal()
  call test_finish()

contains

  !> Random principal moments: isotropic, axisymmetric or triaxial (all > 0).
  function random_inertia(kind) result(inertia)
    integer, intent(in) :: kind
    real(dp) :: inertia(3)
    select case (mod(kind, 3))
    case (0)
      inertia = 1.0_dp + rng%uniform()
    case (1)
      inertia(1:2) = 1.0_dp + rng%uniform()
      inertia(3) = inertia(1)*(0.3_dp + 1.4_dp*rng%uniform())
    case default
      inertia = [0.5_dp + rng%uniform(), 1.0_dp + rng%uniform(), 2.0_dp + rng%uniform()]
    end select
  end function random_inertia

  subroutine random_nodes(nodes, n_nodes)
    real(dp), intent(out) :: nodes(3, max_nodes)
    integer, intent(out) :: n_nodes
    integer :: k
    real(dp) :: half(3)
    n_nodes = 4 + int(rng%uniform()*(max_nodes - 3))
    n_nodes = min(n_nodes, max_nodes)
    half = [0.02_dp + 0.1_dp*rng%uniform(), 0.02_dp + 0.1_dp*rng%uniform(), 0.02_dp + 0.1_dp*rng%uniform()]
    do k = 1, n_nodes
      nodes(:, k) = [rng%symmetric(half(1)), rng%symmetric(half(2)), rng%symmetric(half(3))]
    end do
    if (rng%uniform() < 0.3_dp) then
      ! a box's corners (ties on the supporting plane, symmetric vertex sets)
      n_nodes = 8
      do k = 1, 8
        nodes(:, k) = half*[merge(1.0_dp, -1.0_dp, btest(k - 1, 0)), merge(1.0_dp, -1.0_dp, btest(k - 1, 1)), &
                            merge(1.0_dp, -1.0_dp, btest(k - 1, 2))]
      end do
    end if
  end subroutine random_nodes

  function random_rotation() result(q)
    real(dp) :: q(4)
    q = quat_exp(3.0_dp*rng%uniform()*rng%unit_vector())
  end function random_rotation

  !> Largest m.rho_k over the vertices at orientation q.
  pure real(dp) function highest(q, nodes, m)
    real(dp), intent(in) :: q(4), nodes(:, :), m(3)
    integer :: k
    highest = -huge(1.0_dp)
    do k = 1, size(nodes, 2)
      highest = max(highest, dot_product(m, quat_rotate(q, nodes(:, k))))
    end do
  end function highest

  subroutine one_body_trial(trial, worst_ratio, n_bad, scale)
    integer, intent(in) :: trial
    real(dp), intent(inout) :: worst_ratio
    integer, intent(inout) :: n_bad
    real(dp), intent(in) :: scale
    real(dp) :: nodes(3, max_nodes), inertia(3), q0(4), w0(3), m(3), reach, tau_max, tau, q(4), w(3)
    real(dp) :: c(max_nodes), s(max_nodes), support, rise, bound
    type(free_rotor_t) :: rotor
    type(turning_body_t) :: body
    integer :: n_nodes, it
    call random_nodes(nodes, n_nodes)
    inertia = random_inertia(trial)
    q0 = random_rotation()
    w0 = (0.5_dp + 20.0_dp*rng%uniform())*rng%unit_vector()
    if (mod(trial, 7) == 0) w0 = 0.1_dp*w0
    m = rng%unit_vector()
    reach = maxval(norm2(nodes(:, 1:n_nodes), dim=1))
    body = turning_body([0.0_dp, 0.0_dp, 0.0_dp], q0, w0, [0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], &
                        inertia, reach, 0.0_dp)
    call body_lines(body, nodes(:, 1:n_nodes), m, c(1:n_nodes), s(1:n_nodes), support)
    call rotor%init(inertia, q0, w0)
    ! up to 3 rad of turning; short intervals as often (where the first-order term is sharp)
    tau_max = 3.0_dp*rng%uniform()/norm2(w0)
    if (rng%uniform() < 0.5_dp) tau_max = 1.0e-3_dp*tau_max
    do it = 1, n_times
      tau = tau_max*real(it, dp)/n_times
      call rotor%evaluate(tau, q, w)
      rise = highest(q, nodes(:, 1:n_nodes), m) - highest(q0, nodes(:, 1:n_nodes), m)
      bound = scale*(maxval(c(1:n_nodes) + s(1:n_nodes)*tau) + 0.5_dp*body%curvature*tau*tau)
      ! (round-off of the positions: 1e-15 of the reach)
      if (rise > bound + 1.0e-15_dp*reach) n_bad = n_bad + 1
      if (bound > 1.0e-9_dp*reach) worst_ratio = max(worst_ratio, rise/bound)
    end do
  end subroutine one_body_trial

  subroutine pair_trial(n_bad, worst_fraction)
    integer, intent(inout) :: n_bad
    real(dp), intent(inout) :: worst_fraction
    real(dp) :: nodes_a(3, max_nodes), nodes_b(3, max_nodes), inertia_a(3), inertia_b(3)
    real(dp) :: qa(4), qb(4), wa(3), wb(3), xa(3), xb(3), va(3), vb(3), aa(3), ab(3), n(3)
    real(dp) :: sep0, above, dt, horizon, tau, sep, q(4), w(3), reach_a, reach_b, room
    type(free_rotor_t) :: rotor_a, rotor_b
    type(turning_body_t) :: body_a, body_b
    integer :: na, nb, it
    call random_nodes(nodes_a, na)
    call random_nodes(nodes_b, nb)
    inertia_a = random_inertia(int(3*rng%uniform()))
    inertia_b = random_inertia(int(3*rng%uniform()))
    qa = random_rotation()
    qb = random_rotation()
    wa = 20.0_dp*rng%uniform()*rng%unit_vector()
    wb = 20.0_dp*rng%uniform()*rng%unit_vector()
    n = rng%unit_vector()
    reach_a = maxval(norm2(nodes_a(:, 1:na), dim=1))
    reach_b = maxval(norm2(nodes_b(:, 1:nb), dim=1))
    xa = 0.0_dp
    ! B ahead of A along n by the two reaches and a gap up to 5 cm, offset sideways
    xb = n*(reach_a + reach_b + 0.05_dp*rng%uniform()) + 0.1_dp*[rng%symmetric(1.0_dp), rng%symmetric(1.0_dp), &
                                                                   rng%symmetric(1.0_dp)]
    va = 2.0_dp*rng%uniform()*rng%unit_vector()
    vb = 2.0_dp*rng%uniform()*rng%unit_vector()
    aa = [0.0_dp, 0.0_dp, -9.81_dp]*merge(1.0_dp, 0.0_dp, rng%uniform() < 0.5_dp)
    ab = 10.0_dp*rng%unit_vector()*rng%uniform()
    body_a = turning_body(xa, qa, wa, va, aa, inertia_a, reach_a, 0.0_dp)
    body_b = turning_body(xb, qb, wb, vb, ab, inertia_b, reach_b, 0.0_dp)
    sep0 = separation(xa, qa, nodes_a(:, 1:na), xb, qb, nodes_b(:, 1:nb), n)
    if (sep0 <= 0.0_dp) return
    above = sep0*rng%uniform()
    room = sep0 - above
    horizon = 0.5_dp
    dt = directional_time(body_a, nodes_a(:, 1:na), body_b, nodes_b(:, 1:nb), n, above, horizon)
    call rotor_a%init(inertia_a, qa, wa)
    call rotor_b%init(inertia_b, qb, wb)
    do it = 1, n_times
      tau = min(dt, horizon)*real(it, dp)/n_times
      call rotor_a%evaluate(tau, q, w)
      qa = q
      call rotor_b%evaluate(tau, q, w)
      sep = separation(xa + va*tau + 0.5_dp*aa*tau*tau, qa, nodes_a(:, 1:na), xb + vb*tau + 0.5_dp*ab*tau*tau, q, &
                       nodes_b(:, 1:nb), n)
      if (sep < above - 1.0e-14_dp) n_bad = n_bad + 1
      if (it == n_times .and. dt < horizon) worst_fraction = max(worst_fraction, (sep0 - sep)/room)
    end do
  end subroutine pair_trial

  !> Separation of A and B along n: B's lowest point minus A's highest.
  pure real(dp) function separation(xa, qa, nodes_a, xb, qb, nodes_b, n)
    real(dp), intent(in) :: xa(3), qa(4), nodes_a(:, :), xb(3), qb(4), nodes_b(:, :), n(3)
    separation = dot_product(n, xb - xa) - highest(qb, nodes_b, -n) - highest(qa, nodes_a, n)
  end function separation

  subroutine check_spin_about_normal()
    real(dp) :: cube(3, 8), dt, omega, reach
    type(turning_body_t) :: a, b
    integer :: k
    do k = 1, 8
      cube(:, k) = 0.05_dp*[merge(1.0_dp, -1.0_dp, btest(k - 1, 0)), merge(1.0_dp, -1.0_dp, btest(k - 1, 1)), &
                            merge(1.0_dp, -1.0_dp, btest(k - 1, 2))]
    end do
    reach = 0.05_dp*sqrt(3.0_dp)
    omega = 10.0_dp
    ! A spins about z (the normal), B rests 1 mm above A's top face
    a = turning_body([0.0_dp, 0.0_dp, 0.0_dp], [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, omega], &
                     [0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], [1.0_dp, 1.0_dp, 1.0_dp], reach, 0.0_dp)
    b = turning_body([0.0_dp, 0.0_dp, 0.101_dp], [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], &
                     [0.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], [1.0_dp, 1.0_dp, 1.0_dp], reach, 0.0_dp)
    dt = directional_time(a, cube, b, cube, [0.0_dp, 0.0_dp, 1.0_dp], 0.0_dp, 1.0_dp)
    ! 1 mm = (1 + 1e-12)^2 Omega^2 R t^2/2 (first-order: 1 mm / (Omega R) = 1.2e-3 s)
    call check_close(dt, sqrt(2.0e-3_dp/(omega**2*reach)), 1.0e-9_dp, 'spin about the normal: second order only')
  end subroutine check_spin_about_normal

end program test_turning_bound
