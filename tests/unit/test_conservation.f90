!> System totals: angular momentum about the centre of mass does not depend on where the
!> system is or how fast it moves as a whole (the report must show integration error, not
!> round-off from large orbital terms), and the totals are the hand-computed ones.
program test_conservation
  use kinds, only: dp
  use quaternion, only: quat_exp
  use body_state, only: bodies_t
  use parallel_env, only: parallel_t
  use conservation, only: system_totals_t, compute_totals
  use assertions
  implicit none
  type(parallel_t) :: par
  type(bodies_t) :: b
  type(system_totals_t) :: here, far
  real(dp), parameter :: g(3) = [0.0_dp, 0.0_dp, -9.81_dp]
  integer :: i
  call par%init()
  call b%allocate(3)
  b%n_owned = 3
  b%mass = [1.0_dp, 2.0_dp, 3.0_dp]
  b%inertia = reshape([1.0_dp, 2.0_dp, 3.0_dp, 0.5_dp, 0.5_dp, 0.5_dp, 2.0_dp, 1.0_dp, 1.5_dp], [3, 3])
  b%x = reshape([0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 2.0_dp, 1.0_dp], [3, 3])
  b%v = reshape([1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, -1.0_dp], [3, 3])
  b%w = reshape([0.1_dp, 0.2_dp, 0.3_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 2.0_dp], [3, 3])
  b%q(:, 2) = quat_exp([0.3_dp, 0.2_dp, 0.1_dp])
  b%fixed(3) = .false.
  call compute_totals(par, b, g, here)
  ! hand values: M = 6, P = (1, 2, -3), T_trans = (1 + 2 + 3)/2 = 3
  call check_close(here%mass, 6.0_dp, 0.0_dp, 'total mass')
  call check_close_array(here%momentum, [1.0_dp, 2.0_dp, -3.0_dp], 1.0e-15_dp, 'momentum')
  call check_close(here%kinetic_translational, 3.0_dp, 1.0e-15_dp, 'translational energy')
  call check_close(here%potential, 9.81_dp*3.0_dp, 1.0e-15_dp, 'potential energy -sum m g.x')
  ! Move the whole system 1000 km away and give it 300 m/s more: L about the centre of
  ! mass is the same. Tolerance: the subtraction x - X loses log10(1e6/2) ~ 6 digits of the
  ! positions' 16, so 1e-9 relative.
  do i = 1, 3
    b%x(:, i) = b%x(:, i) + [1.0e6_dp, -2.0e6_dp, 5.0e5_dp]
    b%v(:, i) = b%v(:, i) + [300.0_dp, 0.0_dp, -100.0_dp]
  end do
  call compute_totals(par, b, g, far)
  call check_close_array(far%angular_momentum, here%angular_momentum, 1.0e-9_dp, &
                         'angular momentum about the centre of mass is independent of position and drift')
  call par%free()
  call test_finish()
end program test_conservation
