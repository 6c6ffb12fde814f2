!> The conservative-advancement bound must never be exceeded by real motion, and its root
!> must be the earliest time the bound reaches the gap.
program test_advancement_bound
  use kinds, only: dp
  use quaternion, only: quat_exp, quat_mul, quat_rotate, quat_rotate_inverse
  use random_stream, only: random_stream_t
  use advancement_bound
  use assertions
  implicit none
  type(closing_bound_t) :: bound
  type(random_stream_t) :: rng
  real(dp) :: t, inertia(3), w_body(3), omega, worst_ratio
  integer :: trial

  ! Roots: closing at constant rate, accelerating from rest, decelerating short of the gap.
  bound = closing_bound_t(rate=2.0_dp, acceleration=0.0_dp)
  call check_close(time_to_close(bound, 1.0_dp), 0.5_dp, 0.0_dp, 'constant rate: t = s/b')
  bound = closing_bound_t(rate=0.0_dp, acceleration=9.81_dp)
  call check_close(time_to_close(bound, 1.0_dp), sqrt(2.0_dp/9.81_dp), 4.0_dp*epsilon(1.0_dp), &
                   'free fall from rest: t = sqrt(2 s/g)')
  bound = closing_bound_t(rate=1.0_dp, acceleration=-1.0_dp)     ! reaches at most 1/2
  call check(time_to_close(bound, 0.6_dp) == huge(1.0_dp), 'decelerating pair never closes 0.6 m')
  call check_close(time_to_close(bound, 0.5_dp), 1.0_dp, 1.0e-7_dp, 'grazing root at the apex')
  bound = closing_bound_t(rate=-1.0_dp, acceleration=0.0_dp)
  call check(time_to_close(bound, 1.0_dp) == huge(1.0_dp), 'receding pair never closes')
  ! Zero gap (a pair in contact): when may it start closing?
  call check(time_to_close(closing_bound_t(rate=0.5_dp, acceleration=0.0_dp), 0.0_dp) == 0.0_dp, &
             'zero gap, approaching: now')
  call check(time_to_close(closing_bound_t(rate=-2.0_dp, acceleration=9.81_dp), 0.0_dp) == 4.0_dp/9.81_dp, &
             'zero gap, separating under gravity: back after -2b/a (a bounce)')
  call check(time_to_close(closing_bound_t(rate=0.0_dp, acceleration=0.0_dp), 0.0_dp) == huge(1.0_dp), &
             'zero gap, at rest with no force: never (touching balls of a cradle)')
  bound = closing_bound_t(rate=-1.0_dp, acceleration=2.0_dp)     ! recedes, then returns
  t = time_to_close(bound, 1.0_dp)
  call check_close(closing_distance(bound, t), 1.0_dp, 1.0e-14_dp, 'root solves b t + a t^2/2 = s')
  call check_close(t, (1.0_dp + sqrt(5.0_dp))/2.0_dp, 1.0e-14_dp, 'recede-then-return root: t^2 - t = 1')

  ! The angular speed bound holds along a real torque-free motion (integrated finely):
  ! |w(t)| never exceeds sqrt(2T/I_min). Worst ratio must be <= 1 (1e-12 for round-off).
  call rng%init(11)
  worst_ratio = 0.0_dp
  do trial = 1, 20
    inertia = [1.0_dp + rng%uniform(), 2.0_dp + rng%uniform(), 3.0_dp + rng%uniform()]
    w_body = [rng%symmetric(5.0_dp), rng%symmetric(5.0_dp), rng%symmetric(5.0_dp)]
    omega = angular_speed_bound(inertia, w_body)
    worst_ratio = max(worst_ratio, max_speed_along_motion(inertia, w_body)/omega)
  end do
  call check(worst_ratio <= 1.0_dp + 1.0e-12_dp, 'angular speed bound holds along torque-free motion')
  ! A spin about the axis of least inertia reaches the bound exactly: it is sharp.
  call check_close(angular_speed_bound([1.0_dp, 2.0_dp, 3.0_dp], [5.0_dp, 0.0_dp, 0.0_dp]), 5.0_dp, &
                   1.0e-15_dp, 'bound is sharp for a spin about the minor axis')
  call test_finish()

contains

  !> Largest |w| over 5 s of torque-free motion, by RK4 on Euler's equations (dt 1e-4).
  real(dp) function max_speed_along_motion(inertia, w0) result(largest)
    real(dp), intent(in) :: inertia(3), w0(3)
    real(dp) :: w(3), k1(3), k2(3), k3(3), k4(3), h
    integer :: step
    h = 1.0e-4_dp
    w = w0
    largest = norm2(w)
    do step = 1, 50000
      k1 = euler_rhs(inertia, w)
      k2 = euler_rhs(inertia, w + 0.5_dp*h*k1)
      k3 = euler_rhs(inertia, w + 0.5_dp*h*k2)
      k4 = euler_rhs(inertia, w + h*k3)
      w = w + h/6.0_dp*(k1 + 2.0_dp*k2 + 2.0_dp*k3 + k4)
      largest = max(largest, norm2(w))
    end do
  end function max_speed_along_motion

  pure function euler_rhs(inertia, wb) result(dw)
    real(dp), intent(in) :: inertia(3), wb(3)
    real(dp) :: dw(3)
    dw(1) = (inertia(2) - inertia(3))*wb(2)*wb(3)/inertia(1)
    dw(2) = (inertia(3) - inertia(1))*wb(3)*wb(1)/inertia(2)
    dw(3) = (inertia(1) - inertia(2))*wb(1)*wb(2)/inertia(3)
  end function euler_rhs

end program test_advancement_bound
