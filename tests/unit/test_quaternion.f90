program test_quaternion
  use kinds, only: dp
  use quaternion
  use assertions
  implicit none
  real(dp) :: q(4), r(3, 3), v(3), theta(3)
  theta = [0.3_dp, -0.2_dp, 0.9_dp]
  q = quat_exp(theta)
  call check_close(norm2(q), 1.0_dp, 1.0e-15_dp, 'exp gives a unit quaternion')
  call check_close_array(quat_log(q), theta, 1.0e-14_dp, 'log inverts exp')
  r = quat_to_matrix(q)
  call check_close_array(quat_from_matrix(r), q, 1.0e-14_dp, 'matrix round trip')
  v = [1.0_dp, 2.0_dp, 3.0_dp]
  call check_close_array(quat_rotate(q, v), matmul(r, v), 1.0e-14_dp, 'rotate equals matrix product')
  call check_close_array(quat_rotate_inverse(q, quat_rotate(q, v)), v, 1.0e-14_dp, 'inverse rotation')
  ! rotation about z by pi/2 takes x to y
  q = quat_exp([0.0_dp, 0.0_dp, 2.0_dp*atan(1.0_dp)])
  call check_close_array(quat_rotate(q, [1.0_dp, 0.0_dp, 0.0_dp]), [0.0_dp, 1.0_dp, 0.0_dp], 0.0_dp, &
                         'z quarter turn', atol=1.0e-15_dp)
  call check_close(dot_product(quat_exp([1.0e-9_dp, 0.0_dp, 0.0_dp]), [0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp]), &
                   0.5e-9_dp, 1.0e-15_dp, 'tiny rotation keeps relative accuracy')
  call test_finish()
end program test_quaternion
