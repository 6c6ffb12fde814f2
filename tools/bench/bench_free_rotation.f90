!> Cost of the exact free-rotation propagator (docs/rotation.md): CPU ns per call, 1e6 calls
!> each, on varying times so nothing is hoisted; a checksum keeps the work alive.
!> Build and run with tools/bench_free_rotation.sh (Release library).
program bench_free_rotation
  use kinds, only: dp
  use free_rotation_exact, only: free_rotor_t, exact_rotate
  use elliptic_functions, only: jacobi_sncndn_mc, carlson_rf, carlson_rj
  implicit none
  integer, parameter :: n = 1000000
  type(free_rotor_t) :: rotor
  real(dp) :: q(4), w(3), sum_check, s, c, d, t
  real(dp) :: c0, c1
  integer :: i

  sum_check = 0.0_dp
  call rotor%init([1.0_dp, 2.0_dp, 3.0_dp], [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp], [0.01_dp, 5.0_dp, 0.01_dp])
  call cpu_time(c0)
  do i = 1, n
    t = 1.0e-5_dp*i
    call rotor%evaluate(t, q, w)
    sum_check = sum_check + q(2) + w(3)
  end do
  call cpu_time(c1)
  call report('evaluate, triaxial (elliptic branch)', c1 - c0)

  call cpu_time(c0)
  do i = 1, n
    t = 1.0e-5_dp*i
    call rotor%init([1.0_dp, 2.0_dp, 3.0_dp], [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp], [0.01_dp, 5.0_dp, 0.01_dp + t])
    sum_check = sum_check + rotor%tau0
  end do
  call cpu_time(c1)
  call report('init, triaxial', c1 - c0)

  q = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
  w = [0.01_dp, 5.0_dp, 0.01_dp]
  call cpu_time(c0)
  do i = 1, n
    call exact_rotate(q, w, [1.0_dp, 2.0_dp, 3.0_dp], 1.0e-2_dp)
  end do
  call cpu_time(c1)
  sum_check = sum_check + q(1)
  call report('exact_rotate (init + evaluate), triaxial', c1 - c0)

  call rotor%init([2.0_dp, 2.0_dp, 3.0_dp], [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp], [0.5_dp, 1.0_dp, 2.0_dp])
  call cpu_time(c0)
  do i = 1, n
    call rotor%evaluate(1.0e-5_dp*i, q, w)
    sum_check = sum_check + q(2) + w(3)
  end do
  call cpu_time(c1)
  call report('evaluate, axisymmetric', c1 - c0)

  call cpu_time(c0)
  do i = 1, n
    call jacobi_sncndn_mc(1.0e-5_dp*i, 8.0e-6_dp, s, c, d)
    sum_check = sum_check + s + c + d
  end do
  call cpu_time(c1)
  call report('jacobi_sncndn_mc (mc = 8e-6, incl. K)', c1 - c0)

  call cpu_time(c0)
  do i = 1, n
    sum_check = sum_check + carlson_rf(1.0e-6_dp*i, 0.5_dp, 1.0_dp)
  end do
  call cpu_time(c1)
  call report('carlson_rf', c1 - c0)

  call cpu_time(c0)
  do i = 1, n
    sum_check = sum_check + carlson_rj(1.0e-6_dp*i, 0.5_dp, 1.0_dp, 3.0_dp)
  end do
  call cpu_time(c1)
  call report('carlson_rj', c1 - c0)
  print '(a,es24.16)', 'checksum ', sum_check

contains

  subroutine report(what, seconds)
    character(len=*), intent(in) :: what
    real(dp), intent(in) :: seconds
    print '(a,f8.1,a)', what//': ', 1.0e9_dp*seconds/n, ' ns/call (CPU time)'
  end subroutine report

end program bench_free_rotation
