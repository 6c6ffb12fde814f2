!> Elliptic integrals and Jacobi functions against tabulated values and identities.
!> Sources of the reference values:
!>  - Carlson's symmetric integrals: the check values printed in B. C. Carlson, Numer.
!>    Algorithms 10 (1995) 13-26, Sec. 3 (also DLMF 19.36.i), here to 17 digits.
!>  - K(m), E(m): Abramowitz-Stegun Table 17.1 / DLMF 19.3; F, E(phi), Pi: A&S Tables 17.5,
!>    17.6, 17.9 points; sn, cn, dn: A&S Table 16.x / DLMF 22.x points (e.g. the A&S 16.4
!>    worked example sn(0.75342|0.7) = 0.65137). Tables carry 5-15 digits; the digits used
!>    below are the same values carried to 20 digits with mpmath 1.3 (mp.dps = 30), so the
!>    checks can be held at a few ulps instead of the table's last digit.
!> Tolerances: these algorithms are accurate to a few ulps (Carlson's stopping rule leaves
!> truncation below r = 1.1e-16; each duplication step rounds ~1 ulp), so 2.5 eps = 5.6e-16
!> relative on R_F, R_C, K, F and 5 eps = 1.1e-15 on the sums R_D, R_J, E, Pi, sn, cn, dn.
!> Points whose value comes from a difference of larger terms (near m = 1) get the
!> conditioning factor stated next to them.
program test_elliptic_functions
  use kinds, only: dp
  use constants, only: pi
  use elliptic_functions
  use assertions
  implicit none
  real(dp), parameter :: eps_dp = epsilon(1.0_dp)
  real(dp), parameter :: tight = 2.5_dp*eps_dp, loose = 5.0_dp*eps_dp
  real(dp) :: sn, cn, dn, s1, c1, d1, s2, c2, d2, m, u, v, den, k, e, kp, ep, mc
  integer :: i

  ! ---- Carlson (1995) check values
  call check_close(carlson_rf(1.0_dp, 2.0_dp, 0.0_dp), 1.3110287771460599052_dp, tight, 'R_F(1,2,0)')
  call check_close(carlson_rf(2.0_dp, 3.0_dp, 4.0_dp), 0.58408284167715170669_dp, tight, 'R_F(2,3,4)')
  call check_close(carlson_rc(0.0_dp, 0.25_dp), pi, tight, 'R_C(0,1/4) = pi')
  call check_close(carlson_rc(2.25_dp, 2.0_dp), log(2.0_dp), tight, 'R_C(9/4,2) = ln 2')
  call check_close(carlson_rj(0.0_dp, 1.0_dp, 2.0_dp, 3.0_dp), 0.77688623778582332014_dp, loose, 'R_J(0,1,2,3)')
  call check_close(carlson_rj(2.0_dp, 3.0_dp, 4.0_dp, 5.0_dp), 0.14297579667156753833_dp, loose, 'R_J(2,3,4,5)')
  call check_close(carlson_rd(0.0_dp, 2.0_dp, 1.0_dp), 1.7972103521033883112_dp, loose, 'R_D(0,2,1)')
  call check_close(carlson_rd(2.0_dp, 3.0_dp, 4.0_dp), 0.16510527294261053349_dp, loose, 'R_D(2,3,4)')
  ! Symmetry of R_F in its arguments and homogeneity R_F(lx,ly,lz) = R_F(x,y,z)/sqrt(l)
  ! (DLMF 19.16.i); a permutation changes the rounding only.
  call check_close(carlson_rf(4.0_dp, 2.0_dp, 3.0_dp), carlson_rf(2.0_dp, 3.0_dp, 4.0_dp), tight, 'R_F symmetric')
  call check_close(carlson_rf(3.0_dp, 4.0_dp, 2.0_dp), carlson_rf(2.0_dp, 3.0_dp, 4.0_dp), tight, 'R_F symmetric 2')
  call check_close(carlson_rf(8.0_dp, 12.0_dp, 16.0_dp), 0.5_dp*carlson_rf(2.0_dp, 3.0_dp, 4.0_dp), tight, &
                   'R_F homogeneous')
  ! R_J(x,y,z,z) = R_D(x,y,z) and R_J symmetric in x, y, z.
  call check_close(carlson_rj(2.0_dp, 3.0_dp, 4.0_dp, 4.0_dp), carlson_rd(2.0_dp, 3.0_dp, 4.0_dp), loose, 'R_J(x,y,z,z)=R_D')
  call check_close(carlson_rj(4.0_dp, 2.0_dp, 3.0_dp, 5.0_dp), carlson_rj(2.0_dp, 3.0_dp, 4.0_dp, 5.0_dp), loose, &
                   'R_J symmetric')
  ! The joint R_F, R_J loop equals the separate routines (it may iterate once more: 2 ulps).
  call carlson_rf_rj(0.3_dp, 0.8_dp, 1.0_dp, 4.0_dp, u, v)
  call check_close(u, carlson_rf(0.3_dp, 0.8_dp, 1.0_dp), 2.0_dp*eps_dp, 'carlson_rf_rj: R_F')
  call check_close(v, carlson_rj(0.3_dp, 0.8_dp, 1.0_dp, 4.0_dp), 2.0_dp*eps_dp, 'carlson_rf_rj: R_J')
  ! R_C(x,y) = R_F(x,y,y) (DLMF 19.2.17).
  call check_close(carlson_rc(0.3_dp, 1.7_dp), carlson_rf(0.3_dp, 1.7_dp, 1.7_dp), tight, 'R_C = R_F(x,y,y)')
  ! p < 0 is documented as not provided.
  call check(carlson_rj(1.0_dp, 2.0_dp, 3.0_dp, -1.0_dp) /= carlson_rj(1.0_dp, 2.0_dp, 3.0_dp, -1.0_dp), &
             'R_J with p < 0 returns NaN')

  ! ---- complete integrals (A&S Table 17.1)
  call check_close(elliptic_k(0.0_dp), 0.5_dp*pi, tight, 'K(0) = pi/2')
  call check_close(elliptic_e(0.0_dp), 0.5_dp*pi, tight, 'E(0) = pi/2')
  call check_close(elliptic_e(1.0_dp), 1.0_dp, 0.0_dp, 'E(1) = 1')
  call check(elliptic_k(1.0_dp) > huge(1.0_dp), 'K(1) = +Inf')
  call check_close(elliptic_k(0.1_dp), 1.6124413487202193982_dp, tight, 'K(0.1)')
  call check_close(elliptic_e(0.1_dp), 1.5307576368977632025_dp, loose, 'E(0.1)')
  call check_close(elliptic_k(0.5_dp), 1.8540746773013719184_dp, tight, 'K(0.5)')
  call check_close(elliptic_e(0.5_dp), 1.3506438810476755025_dp, loose, 'E(0.5)')
  call check_close(elliptic_k(0.9_dp), 2.5780921133481731882_dp, tight, 'K(0.9)')
  call check_close(elliptic_e(0.9_dp), 1.1047747327040733261_dp, loose, 'E(0.9)')
  call check_close(elliptic_k(0.99_dp), 3.6956373629898746778_dp, tight, 'K(0.99)')
  call check_close(elliptic_e(0.99_dp), 1.0159935450252239356_dp, loose, 'E(0.99)')
  ! Near m = 1 through the complementary parameter (mc = 1e-6 exactly representable
  ! relative to itself, unlike 1 - 0.999999).
  call check_close(elliptic_k_mc(1.0e-6_dp), 8.2940514636154399853_dp, tight, 'K(mc = 1e-6)')
  call check_close(elliptic_e_mc(1.0e-6_dp), 1.0000038970261720612_dp, loose, 'E(mc = 1e-6)')
  ! Legendre's relation E K' + E' K - K K' = pi/2 (DLMF 19.7.1), several m: the three
  ! products are O(1-10), so 4 ulps of the largest (K K' <= 10 here) as absolute tolerance.
  do i = 1, 9
    m = 0.1_dp*i
    k = elliptic_k(m); e = elliptic_e(m); kp = elliptic_k_mc(m); ep = elliptic_e_mc(m)
    call check_close(e*kp + ep*k - k*kp, 0.5_dp*pi, 0.0_dp, 'Legendre relation', atol=4.0_dp*epsilon(1.0_dp)*k*kp)
  end do

  ! ---- incomplete integrals (A&S Tables 17.5, 17.6, 17.9 points)
  call check_close(elliptic_f(pi/6.0_dp, 0.25_dp), 0.52942862705190581774_dp, tight, 'F(30 deg|0.25)')
  call check_close(elliptic_f(pi/3.0_dp, 0.75_dp), 1.2125966152549791201_dp, tight, 'F(60 deg|0.75)')
  call check_close(elliptic_f(1.3_dp, 0.99_dp), 1.966094463354886885_dp, tight, 'F(1.3|0.99)')
  call check_close(elliptic_e_inc(pi/3.0_dp, 0.75_dp), 0.91839329431632533119_dp, loose, 'E(60 deg|0.75)')
  call check_close(elliptic_pi(0.5_dp, 0.25_dp*pi, 0.5_dp), 0.9190227391656969904_dp, loose, 'Pi(0.5; 45 deg|0.5)')
  call check_close(elliptic_pi(-3.0_dp, 1.2_dp, 0.8_dp), 0.7961897302797488431_dp, loose, 'Pi(-3; 1.2|0.8)')
  call check_close(elliptic_pi_complete(-3.0_dp, 0.8_dp), 0.99481063000486693884_dp, loose, 'Pi(-3|0.8)')
  ! Beyond pi/2 by quasi-periodicity: Pi(n; phi + j pi) = Pi(n; phi) + 2 j Pi(n); the result
  ! 5.75 is a sum of terms up to 4.6, so one more ulp.
  call check_close(elliptic_pi(0.3_dp, 4.0_dp, 0.6_dp), 5.7497791943184748973_dp, 1.2e-15_dp, 'Pi(0.3; 4|0.6)')
  call check_close(elliptic_f(0.5_dp*pi, 0.7_dp), elliptic_k(0.7_dp), tight, 'F(pi/2) = K')
  call check_close(elliptic_f(-2.0_dp, 0.7_dp), -elliptic_f(2.0_dp, 0.7_dp), tight, 'F odd')
  call check_close(elliptic_f(0.4_dp + 3.0_dp*pi, 0.7_dp), elliptic_f(0.4_dp, 0.7_dp) + 6.0_dp*elliptic_k(0.7_dp), &
                   loose, 'F quasi-periodic')
  call check_close(elliptic_pi(0.0_dp, 1.1_dp, 0.3_dp), elliptic_f(1.1_dp, 0.3_dp), tight, 'Pi(0; phi) = F')

  ! ---- Jacobi functions (A&S 16 / DLMF 22 points)
  call jacobi_sncndn(0.75342_dp, 0.7_dp, sn, cn, dn)
  call check_close_array([sn, cn, dn], [0.65137351261317604322_dp, 0.75875723855919331198_dp, &
                         0.83845022687466714829_dp], loose, 'sn cn dn (0.75342|0.7)')
  call jacobi_sncndn(0.2_dp, 0.81_dp, sn, cn, dn)
  call check_close_array([sn, cn, dn], [0.19762082367187648571_dp, 0.98027853697367520321_dp, &
                         0.98405602896456651553_dp], loose, 'sn cn dn (0.2|0.81)')
  call jacobi_sncndn(10.0_dp, 0.3_dp, sn, cn, dn)
  ! u = 10 is 2.9 half periods away: the reduction u - 2jK rounds once more (4 ulps of 10
  ! in u, times |d sn/du| <= 1) so 2e-15 absolute.
  call check_close_array([sn, cn, dn], [0.27848731626489941008_dp, -0.96043990685496502462_dp, &
                         0.98829825680503563648_dp], 0.0_dp, 'sn cn dn (10|0.3) reduced', atol=2.0e-15_dp)
  call jacobi_sncndn_mc(1.5_dp, 1.0e-6_dp, sn, cn, dn)
  ! (1.5|1 - 1e-6) with mc given exactly.
  call check_close_array([sn, cn, dn], [0.90514841216687817683_dp, 0.42509569740445412143_dp, &
                         0.42509666106125471506_dp], loose, 'sn cn dn (1.5|mc=1e-6)')
  call jacobi_sncndn(3.0_dp, 1.0_dp, sn, cn, dn)
  call check_close_array([sn, cn, dn], [tanh(3.0_dp), 1.0_dp/cosh(3.0_dp), 1.0_dp/cosh(3.0_dp)], 0.0_dp, &
                         'm = 1 is tanh, sech exactly')
  call jacobi_sncndn(800.0_dp, 1.0_dp, sn, cn, dn)
  call check(sn == 1.0_dp .and. cn >= 0.0_dp .and. cn < 1.0e-300_dp, 'm = 1 huge u: no overflow')
  call jacobi_sncndn(1.3_dp, 0.0_dp, sn, cn, dn)
  call check_close_array([sn, cn, dn], [sin(1.3_dp), cos(1.3_dp), 1.0_dp], 2.0_dp*epsilon(1.0_dp), 'm = 0 is sin, cos, 1')
  call check_close(jacobi_am(elliptic_f(1.1_dp, 0.6_dp), 0.6_dp), 1.1_dp, loose, 'am inverts F')
  call check_close(jacobi_am(elliptic_f(40.0_dp, 0.6_dp), 0.6_dp), 40.0_dp, loose, 'am unwrapped over 12 half periods')
  call check_close(jacobi_am(elliptic_k(0.6_dp), 0.6_dp), 0.5_dp*pi, loose, 'am(K) = pi/2')

  ! Identities over a sweep of u and m, including m within 1e-12 of 1 through mc:
  ! sn^2 + cn^2 = 1, dn^2 + m sn^2 = 1 (DLMF 22.6.1) to 4 ulps, and the addition theorem
  ! sn(u+v) = (sn cn dn(v) + sn(v) cn dn)/(1 - m sn^2 sn(v)^2) (DLMF 22.8.1) to 8 ulps of
  ! its O(1) terms (the denominator is >= 1 - m, so near m = 1 the points are kept where
  ! it is >= 0.1: the formula's own conditioning, not the functions').
  do i = 0, 40
    mc = 10.0_dp**(-0.3_dp*i)
    m = 1.0_dp - mc
    u = 0.37_dp + 0.61_dp*i
    v = 1.9_dp - 0.13_dp*i
    call jacobi_sncndn_mc(u, mc, s1, c1, d1)
    call check_close(s1**2 + c1**2, 1.0_dp, 4.0_dp*epsilon(1.0_dp), 'sn^2 + cn^2 = 1')
    call check_close(d1**2 + m*s1**2, 1.0_dp, 4.0_dp*epsilon(1.0_dp), 'dn^2 + m sn^2 = 1')
    call jacobi_sncndn_mc(v, mc, s2, c2, d2)
    den = 1.0_dp - m*s1**2*s2**2
    if (den >= 0.1_dp) then
      call jacobi_sncndn_mc(u + v, mc, sn, cn, dn)
      call check_close(sn, (s1*c2*d2 + s2*c1*d1)/den, 0.0_dp, 'sn addition theorem', &
                       atol=8.0_dp*epsilon(1.0_dp)/den)
      call check_close(cn, (c1*c2 - s1*d1*s2*d2)/den, 0.0_dp, 'cn addition theorem', &
                       atol=8.0_dp*epsilon(1.0_dp)/den)
      call check_close(dn, (d1*d2 - m*s1*c1*s2*c2)/den, 0.0_dp, 'dn addition theorem', &
                       atol=8.0_dp*epsilon(1.0_dp)/den)
    end if
  end do
  call test_finish()
end program test_elliptic_functions
