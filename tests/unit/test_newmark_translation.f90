!> Free fall with Newmark: with a constant acceleration g (a_n = a_{n+1} = g) the update
!> x + h v + h^2/2 g, v + h g is the exact parabola for every (beta, gamma), so after N
!> steps the only difference to x0 + v0 t + g t^2/2 is accumulated round-off. Also: the
!> free-flight driver skips fixed bodies and ghosts, and spheres and bodies at rest rotate
!> without iterating.
program test_newmark_translation
  use kinds, only: dp
  use quaternion, only: quat_identity, quat_exp, quat_angle_between, quat_rotate, quat_rotate_inverse
  use body_state, only: bodies_t
  use input_config, only: integrator_config_t
  use newmark_integrator, only: newmark_translate, newmark_rotate, advance_free_flight, &
                                free_flight_stats_t, is_isotropic
  use assertions
  implicit none

  integer, parameter :: n_states = 3, n_params = 4, n_steps = 1000
  real(dp), parameter :: g(3) = [0.0_dp, 0.0_dp, -9.81_dp]        ! [m/s^2]
  real(dp), parameter :: h = 1.0e-3_dp                            ! [s]
  real(dp) :: x0(3, n_states), v0(3, n_states), params(2, n_params)
  real(dp) :: x(3), v(3), a(3), t, x_exact(3), v_exact(3), scale_x, scale_v, err_x, err_v
  integer :: s, p, n
  character(len=96) :: label

  x0 = reshape([0.0_dp, 0.0_dp, 0.0_dp, 1.5_dp, -2.0_dp, 10.0_dp, -100.0_dp, 3.0_dp, 0.25_dp], [3, n_states])
  v0 = reshape([0.0_dp, 0.0_dp, 0.0_dp, 3.0_dp, 0.5_dp, 4.0_dp, -20.0_dp, 1.0e-3_dp, 50.0_dp], [3, n_states])
  ! (beta, gamma): explicit central difference, Fox-Goodwin, average acceleration (the
  ! default), and a dissipative gamma = 0.6 choice (exact too with constant acceleration).
  params = reshape([0.0_dp, 0.5_dp, 1.0_dp/12.0_dp, 0.5_dp, 0.25_dp, 0.5_dp, 0.3025_dp, 0.6_dp], [2, n_params])

  do p = 1, n_params
    do s = 1, n_states
      x = x0(:, s)
      v = v0(:, s)
      a = g              ! the Newmark state: acceleration at t_0
      err_x = 0.0_dp
      err_v = 0.0_dp
      do n = 1, n_steps
        call newmark_translate(x, v, a, g, h, params(1, p), params(2, p))
        t = n*h
        x_exact = x0(:, s) + v0(:, s)*t + 0.5_dp*g*t*t
        v_exact = v0(:, s) + g*t
        ! Round-off scale: the largest term of each sum (what one rounding is relative to).
        scale_x = maxval(abs(x0(:, s))) + maxval(abs(v0(:, s)))*t + 0.5_dp*maxval(abs(g))*t*t
        scale_v = maxval(abs(v0(:, s))) + maxval(abs(g))*t
        err_x = max(err_x, maxval(abs(x - x_exact))/scale_x)
        err_v = max(err_v, maxval(abs(v - v_exact))/scale_v)
      end do
      write (*, '(a,2f8.4,a,i0,a,2es10.2)') 'beta, gamma =', params(:, p), ' state ', s, &
        ': max rel. error x, v: ', err_x, err_v
      ! Each step adds a few rounded terms to x (about 4 roundings of size eps*scale), so N
      ! steps accumulate at most ~4 N eps relative in the worst case, ~sqrt(N) eps
      ! typically (measured: at most 4.3e-14 = 190 eps for N = 1000). Bound N eps = 2.2e-13:
      ! the exact parabola up to round-off, while any truncation error (e.g. a_n not used,
      ! h^2 g/2 replaced by h^2 g beta) is ~h = 1e-3 relative, ten orders more.
      write (label, '(a,2f7.4,a,i0)') 'free fall x on the parabola, beta, gamma =', params(:, p), ', state ', s
      call check(err_x <= n_steps*epsilon(1.0_dp), trim(label))
      write (label, '(a,2f7.4,a,i0)') 'free fall v on the line, beta, gamma =', params(:, p), ', state ', s
      call check(err_v <= n_steps*epsilon(1.0_dp), trim(label))
      call check(all(a == g), 'acceleration state becomes the new acceleration')
    end do
  end do

  call check_driver()
  call check_skips()
  call test_finish()

contains

  !> advance_free_flight moves owned non-fixed bodies only, and counts its work.
  subroutine check_driver()
    type(bodies_t) :: bodies
    type(integrator_config_t) :: config
    type(free_flight_stats_t) :: stats
    integer :: i
    call bodies%allocate(4)
    bodies%n_owned = 3
    bodies%n_ghost = 1
    bodies%fixed(2) = .true.
    bodies%inertia(:, 1) = [1.0_dp, 2.0_dp, 3.0_dp]     ! tumbling plate
    bodies%inertia(:, 2) = [1.0_dp, 2.0_dp, 3.0_dp]     ! fixed
    bodies%inertia(:, 3) = [0.4_dp, 0.4_dp, 0.4_dp]     ! sphere
    bodies%inertia(:, 4) = [1.0_dp, 2.0_dp, 3.0_dp]     ! ghost
    do i = 1, 4
      bodies%v(:, i) = [1.0_dp, 0.0_dp, 0.0_dp]
      bodies%w(:, i) = [0.01_dp, 5.0_dp, 0.01_dp]
      bodies%a(:, i) = g
    end do
    call advance_free_flight(bodies, h, g, config, stats)
    ! Exact values: one step of the parabola; 1 ulp-level tolerance.
    call check_close_array(bodies%x(:, 1), [h, 0.0_dp, 0.5_dp*g(3)*h*h], 1.0e-15_dp, 'free body moved', atol=1.0e-20_dp)
    call check(all(bodies%x(:, 2) == 0.0_dp) .and. all(bodies%w(:, 2) == [0.01_dp, 5.0_dp, 0.01_dp]) .and. &
               all(bodies%q(:, 2) == quat_identity), 'fixed body untouched')
    call check(all(bodies%x(:, 4) == 0.0_dp) .and. all(bodies%q(:, 4) == quat_identity), 'ghost untouched')
    call check(stats%rotation_updates == 1, 'one body iterated (the plate)')
    call check(stats%rotation_skipped == 1, 'one body skipped the iteration (the sphere)')
    call check(stats%iterations_total >= 2 .and. stats%iterations_max >= 2, &
               'iteration counts reported (>= 2: the predictor is not exact)')
    call check(stats%not_converged == 0, 'no unconverged update')
    config%rotation_max_iterations = 1
    call advance_free_flight(bodies, h, g, config, stats)
    call check(stats%not_converged == 1, 'an unconverged update is counted')
    call check(stats%rotation_updates == 2 .and. stats%rotation_skipped == 2, 'statistics accumulate over calls')
    call bodies%free()
  end subroutine check_driver

  !> Torque-free spheres and bodies at rest need no iteration and are exact: w constant,
  !> q_{n+1} = exp(h w) q_n (so after N steps, exp(N h w) q_0, to round-off).
  subroutine check_skips()
    real(dp) :: q(4), w(3), alpha(3), w0(3)
    integer :: iterations, n
    logical :: converged
    call check(is_isotropic([0.4_dp, 0.4_dp, 0.4_dp*(1.0_dp + 1.0e-15_dp)]), 'round-off-equal moments are isotropic')
    call check(.not. is_isotropic([0.4_dp, 0.4_dp, 0.4_dp*(1.0_dp + 1.0e-12_dp)]), '1e-12 apart is not isotropic')
    w0 = [0.3_dp, -2.0_dp, 7.0_dp]
    q = quat_identity
    w = w0
    do n = 1, 1000
      call newmark_rotate(q, w, alpha, [0.4_dp, 0.4_dp, 0.4_dp], [0.0_dp, 0.0_dp, 0.0_dp], h, 0.25_dp, 0.5_dp, &
                          1.0e-14_dp, 50, iterations, converged)
      if (iterations /= 0) exit
    end do
    call check(iterations == 0 .and. converged, 'sphere: no iteration')
    call check(all(w == w0), 'sphere: w unchanged')
    ! 1000 compositions of exp(h w), each rounded at ~eps: angle error ~1000 eps = 2e-13 rad
    ! at most; bound 1e-12 rad (the rotation angle itself is 7.3 rad).
    call check(quat_angle_between(q, quat_exp(1000*h*w0)) < 1.0e-12_dp, 'sphere: q = exp(t w) q0')
    q = quat_exp([0.1_dp, 0.2_dp, 0.3_dp])
    w = 0.0_dp
    call newmark_rotate(q, w, alpha, [1.0_dp, 2.0_dp, 3.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], h, 0.25_dp, 0.5_dp, &
                        1.0e-14_dp, 50, iterations, converged)
    call check(iterations == 0 .and. all(q == quat_exp([0.1_dp, 0.2_dp, 0.3_dp])) .and. all(w == 0.0_dp), &
               'body at rest: no iteration, no change')
    ! With a torque the body at rest starts turning: L = h tau exactly after one step.
    call newmark_rotate(q, w, alpha, [1.0_dp, 2.0_dp, 3.0_dp], [0.0_dp, 0.0_dp, 2.0_dp], h, 0.25_dp, 0.5_dp, &
                        1.0e-14_dp, 50, iterations, converged)
    call check(iterations > 0 .and. converged, 'torque: iterated')
    ! L_1 = L_0 + h tau = (0, 0, 2e-3) N m s; a few roundings of size eps*|L|: atol 1e-17.
    call check_close_array(quat_rotate(q, [1.0_dp, 2.0_dp, 3.0_dp]*quat_rotate_inverse(q, w)), &
                           [0.0_dp, 0.0_dp, 2.0_dp*h], 0.0_dp, 'torque: L = h tau after one step', atol=1.0e-17_dp)
  end subroutine check_skips

end program test_newmark_translation
