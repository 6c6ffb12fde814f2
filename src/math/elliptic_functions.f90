!> Elliptic integrals and Jacobi elliptic functions in double precision, written from the
!> standard numerically stable algorithms:
!>  - Carlson's symmetric integrals R_F, R_D, R_J, R_C by duplication with the fifth-order
!>    series of B. C. Carlson, "Numerical computation of real or complex elliptic integrals",
!>    Numer. Algorithms 10 (1995) 13-26 (also DLMF 19.36.i). The stopping rule is Carlson's:
!>    iterate until 4^-n Q < |A_n|, which leaves a truncation error below one ulp.
!>  - Legendre forms through DLMF 19.25.5, 19.25.7, 19.25.14 (F, E, Pi from R_F, R_D, R_J).
!>  - sn, cn, dn by the descending Landen / AGM scheme of R. Bulirsch, Numer. Math. 7 (1965)
!>    78-90 (the `sncndn` of Numerical Recipes), after reducing the argument by the real
!>    period 4K so huge arguments keep their accuracy (as far as u itself is known).
!>
!> Convention: the PARAMETER m = k^2 (DLMF, Abramowitz-Stegun "m"), 0 <= m <= 1, and the
!> characteristic n of the third kind enters as 1/(1 - n sin^2 theta) (A&S 17.2.15, DLMF
!> 19.2.7 with alpha^2 = n). Every routine has a companion taking the complementary
!> parameter mc = 1 - m (suffix _mc): near m = 1 the caller often knows mc to full relative
!> accuracy while 1 - m rounded from m does not, and K, sn, cn, dn depend on mc, not m.
!>
!> Domain: x, y, z >= 0 with at most one zero, p > 0, y > 0 for R_C. The Cauchy principal
!> values (p < 0, i.e. n sin^2 phi > 1) are NOT provided: those calls return NaN. m outside
!> [0, 1] also returns NaN. Nothing here stops or allocates; everything is elemental.
module elliptic_functions
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_quiet_nan
  use kinds, only: dp
  use constants, only: pi
  implicit none
  private
  public :: carlson_rf, carlson_rd, carlson_rj, carlson_rc
  public :: elliptic_k, elliptic_k_mc, elliptic_e, elliptic_e_mc, elliptic_pi_complete, &
            elliptic_pi_complete_mc
  public :: elliptic_f, elliptic_f_mc, elliptic_e_inc, elliptic_e_inc_mc, elliptic_pi, elliptic_pi_mc
  public :: jacobi_sncndn, jacobi_sncndn_mc, jacobi_sncndn_core, jacobi_am, jacobi_am_mc
  public :: jacobi_agm_table, jacobi_sncndn_table, jacobi_agm_max_steps, carlson_rf_rj

  !> Unit roundoff of real(dp) (2^-53), the r of Carlson's stopping rule.
  real(dp), parameter :: unit_roundoff = 0.5_dp*epsilon(1.0_dp)
  !> Carlson's Q factors: (3r)^(-1/6) for R_F, (r/4)^(-1/6) for R_D and R_J, (3r)^(-1/8) for
  !> R_C make the neglected series terms of the last duplication step smaller than r.
  real(dp), parameter :: q_rf = (3.0_dp*unit_roundoff)**(-1.0_dp/6.0_dp)
  real(dp), parameter :: q_rd = (0.25_dp*unit_roundoff)**(-1.0_dp/6.0_dp)
  real(dp), parameter :: q_rc = (3.0_dp*unit_roundoff)**(-1.0_dp/8.0_dp)
  !> Landen/AGM stops when |a - b| <= ca a: the next (quadratic) step would change the
  !> result by ~ca^2 = 1e-16 relative, i.e. below one ulp.
  real(dp), parameter :: agm_tolerance = 1.0e-8_dp
  !> Enough AGM steps for mc down to the smallest normal number (convergence is quadratic
  !> once a/b = O(1); a/b = 1e154 needs ~9 steps).
  integer, parameter :: jacobi_agm_max_steps = 24
  !> Beyond this |u| at m = 1, cosh overflows; sech u = 2 exp(-|u|) there to full accuracy.
  real(dp), parameter :: sech_asymptotic = 40.0_dp

contains

  pure real(dp) function nan_value()
    nan_value = ieee_value(0.0_dp, ieee_quiet_nan)
  end function nan_value

  ! ------------------------------------------------------------------ Carlson forms

  !> R_F(x,y,z) = 1/2 int_0^inf dt / sqrt((t+x)(t+y)(t+z))   (DLMF 19.16.1)
  elemental real(dp) function carlson_rf(x, y, z) result(rf)
    real(dp), intent(in) :: x, y, z
    real(dp) :: xn, yn, zn, a0, an, q, lam, sx, sy, sz, xd, yd, zd, e2, e3, f4
    if (min(x, y, z) < 0.0_dp .or. min(x + y, x + z, y + z) <= 0.0_dp) then
      rf = nan_value()
      return
    end if
    xn = x; yn = y; zn = z
    a0 = (x + y + z)/3.0_dp
    an = a0
    q = q_rf*max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    f4 = 1.0_dp
    do while (q*f4 >= abs(an))
      sx = sqrt(xn); sy = sqrt(yn); sz = sqrt(zn)
      lam = sx*sy + sx*sz + sy*sz
      an = 0.25_dp*(an + lam)
      xn = 0.25_dp*(xn + lam); yn = 0.25_dp*(yn + lam); zn = 0.25_dp*(zn + lam)
      f4 = 0.25_dp*f4
    end do
    xd = (a0 - x)*f4/an
    yd = (a0 - y)*f4/an
    zd = -(xd + yd)
    e2 = xd*yd - zd*zd
    e3 = xd*yd*zd
    rf = (1.0_dp - e2/10.0_dp + e3/14.0_dp + e2*e2/24.0_dp - 3.0_dp*e2*e3/44.0_dp)/sqrt(an)
  end function carlson_rf

  !> R_D(x,y,z) = R_J(x,y,z,z) = 3/2 int_0^inf dt / ((t+z) sqrt((t+x)(t+y)(t+z)))  (DLMF 19.16.5)
  elemental real(dp) function carlson_rd(x, y, z) result(rd)
    real(dp), intent(in) :: x, y, z
    real(dp) :: xn, yn, zn, a0, an, q, lam, sx, sy, sz, xd, yd, zd, e2, e3, e4, e5, f4, s, xy
    if (min(x, y) < 0.0_dp .or. x + y <= 0.0_dp .or. z <= 0.0_dp) then
      rd = nan_value()
      return
    end if
    xn = x; yn = y; zn = z
    a0 = (x + y + 3.0_dp*z)/5.0_dp
    an = a0
    q = q_rd*max(abs(a0 - x), abs(a0 - y), abs(a0 - z))
    f4 = 1.0_dp
    s = 0.0_dp
    do while (q*f4 >= abs(an))
      sx = sqrt(xn); sy = sqrt(yn); sz = sqrt(zn)
      lam = sx*sy + sx*sz + sy*sz
      s = s + f4/(sz*(zn + lam))
      an = 0.25_dp*(an + lam)
      xn = 0.25_dp*(xn + lam); yn = 0.25_dp*(yn + lam); zn = 0.25_dp*(zn + lam)
      f4 = 0.25_dp*f4
    end do
    xd = (a0 - x)*f4/an
    yd = (a0 - y)*f4/an
    zd = -(xd + yd)/3.0_dp
    xy = xd*yd
    e2 = xy - 6.0_dp*zd*zd
    e3 = (3.0_dp*xy - 8.0_dp*zd*zd)*zd
    e4 = 3.0_dp*(xy - zd*zd)*zd*zd
    e5 = xy*zd*zd*zd
    rd = f4*(1.0_dp - 3.0_dp*e2/14.0_dp + e3/6.0_dp + 9.0_dp*e2*e2/88.0_dp - 3.0_dp*e4/22.0_dp &
             - 9.0_dp*e2*e3/52.0_dp + 3.0_dp*e5/26.0_dp)/(an*sqrt(an)) + 3.0_dp*s
  end function carlson_rd

  !> R_C(x,y) = 1/2 int_0^inf dt / ((t+y) sqrt(t+x)), y > 0 (DLMF 19.2.17). The Cauchy
  !> principal value for y < 0 is not provided (NaN).
  elemental real(dp) function carlson_rc(x, y) result(rc)
    real(dp), intent(in) :: x, y
    real(dp) :: xn, yn, a0, an, q, lam, f4, s
    if (x < 0.0_dp .or. y <= 0.0_dp) then
      rc = nan_value()
      return
    end if
    xn = x; yn = y
    a0 = (x + 2.0_dp*y)/3.0_dp
    an = a0
    q = q_rc*abs(a0 - x)
    f4 = 1.0_dp
    do while (q*f4 >= abs(an))
      lam = 2.0_dp*sqrt(xn)*sqrt(yn) + yn
      an = 0.25_dp*(an + lam)
      xn = 0.25_dp*(xn + lam); yn = 0.25_dp*(yn + lam)
      f4 = 0.25_dp*f4
    end do
    s = (y - a0)*f4/an
    rc = (1.0_dp + s*s*(3.0_dp/10.0_dp + s*(1.0_dp/7.0_dp + s*(3.0_dp/8.0_dp + s*(9.0_dp/22.0_dp &
         + s*(159.0_dp/208.0_dp + s*9.0_dp/8.0_dp))))))/sqrt(an)
  end function carlson_rc

  !> R_C(1, 1 + e) for e > -1 in closed form (atan / atanh over sqrt), by its Taylor series
  !> when |e| is small so no cancellation occurs. Used inside R_J, where e -> 0 quickly.
  elemental real(dp) function rc_one(e) result(rc)
    real(dp), intent(in) :: e
    real(dp) :: r
    if (abs(e) < 1.0e-3_dp) then
      ! 1 - e/3 + e^2/5 - e^3/7 + e^4/9 - e^5/11; next term e^6/13 < 1e-19.
      rc = 1.0_dp + e*(-1.0_dp/3.0_dp + e*(1.0_dp/5.0_dp + e*(-1.0_dp/7.0_dp + e*(1.0_dp/9.0_dp &
           - e/11.0_dp))))
    else if (e > 0.0_dp) then
      r = sqrt(e)
      rc = atan(r)/r
    else
      r = sqrt(-e)
      rc = atanh(r)/r
    end if
  end function rc_one

  !> R_J(x,y,z,p) = 3/2 int_0^inf dt / ((t+p) sqrt((t+x)(t+y)(t+z))), p > 0 (DLMF 19.16.2).
  !> p < 0 (Cauchy principal value) is not provided: returns NaN.
  elemental real(dp) function carlson_rj(x, y, z, p) result(rj)
    real(dp), intent(in) :: x, y, z, p
    real(dp) :: xn, yn, zn, pn, a0, an, q, lam, sx, sy, sz, sp, dm, em, delta, f4, f64, s
    real(dp) :: xd, yd, zd, pd, e2, e3, e4, e5
    if (min(x, y, z) < 0.0_dp .or. min(x + y, x + z, y + z) <= 0.0_dp .or. p <= 0.0_dp) then
      rj = nan_value()
      return
    end if
    xn = x; yn = y; zn = z; pn = p
    a0 = (x + y + z + 2.0_dp*p)/5.0_dp
    an = a0
    delta = (p - x)*(p - y)*(p - z)
    q = q_rd*max(abs(a0 - x), abs(a0 - y), abs(a0 - z), abs(a0 - p))
    f4 = 1.0_dp
    f64 = 1.0_dp
    s = 0.0_dp
    do while (q*f4 >= abs(an))
      sx = sqrt(xn); sy = sqrt(yn); sz = sqrt(zn); sp = sqrt(pn)
      lam = sx*sy + sx*sz + sy*sz
      dm = (sp + sx)*(sp + sy)*(sp + sz)
      em = f64*delta/(dm*dm)
      s = s + f4/dm*rc_one(em)
      an = 0.25_dp*(an + lam)
      xn = 0.25_dp*(xn + lam); yn = 0.25_dp*(yn + lam); zn = 0.25_dp*(zn + lam)
      pn = 0.25_dp*(pn + lam)
      f4 = 0.25_dp*f4
      f64 = f64/64.0_dp
    end do
    xd = (a0 - x)*f4/an
    yd = (a0 - y)*f4/an
    zd = (a0 - z)*f4/an
    pd = -0.5_dp*(xd + yd + zd)
    e2 = xd*yd + xd*zd + yd*zd - 3.0_dp*pd*pd
    e3 = xd*yd*zd + 2.0_dp*e2*pd + 4.0_dp*pd*pd*pd
    e4 = (2.0_dp*xd*yd*zd + e2*pd + 3.0_dp*pd*pd*pd)*pd
    e5 = xd*yd*zd*pd*pd
    rj = f4*(1.0_dp - 3.0_dp*e2/14.0_dp + e3/6.0_dp + 9.0_dp*e2*e2/88.0_dp - 3.0_dp*e4/22.0_dp &
             - 9.0_dp*e2*e3/52.0_dp + 3.0_dp*e5/26.0_dp)/(an*sqrt(an)) + 6.0_dp*s
  end function carlson_rj

  !> R_F(x,y,z) and R_J(x,y,z,p) together (p > 0): both duplicate the same x, y, z, so one
  !> loop serves both (Pi(n; phi|m) needs exactly this pair). Iterates until both of
  !> Carlson's stopping rules hold; results equal the separate routines to round-off.
  elemental subroutine carlson_rf_rj(x, y, z, p, rf, rj)
    real(dp), intent(in) :: x, y, z, p
    real(dp), intent(out) :: rf, rj
    real(dp) :: xn, yn, zn, pn, a0f, anf, a0, an, qf, q, lam, sx, sy, sz, sp, dm, em, delta, f4, f64, s
    real(dp) :: xd, yd, zd, pd, e2, e3, e4, e5
    if (min(x, y, z) < 0.0_dp .or. min(x + y, x + z, y + z) <= 0.0_dp .or. p <= 0.0_dp) then
      rf = nan_value()
      rj = rf
      return
    end if
    xn = x; yn = y; zn = z; pn = p
    a0f = (x + y + z)/3.0_dp
    anf = a0f
    a0 = (x + y + z + 2.0_dp*p)/5.0_dp
    an = a0
    delta = (p - x)*(p - y)*(p - z)
    qf = q_rf*max(abs(a0f - x), abs(a0f - y), abs(a0f - z))
    q = q_rd*max(abs(a0 - x), abs(a0 - y), abs(a0 - z), abs(a0 - p))
    f4 = 1.0_dp
    f64 = 1.0_dp
    s = 0.0_dp
    do while (q*f4 >= abs(an) .or. qf*f4 >= abs(anf))
      sx = sqrt(xn); sy = sqrt(yn); sz = sqrt(zn); sp = sqrt(pn)
      lam = sx*sy + sx*sz + sy*sz
      dm = (sp + sx)*(sp + sy)*(sp + sz)
      em = f64*delta/(dm*dm)
      s = s + f4/dm*rc_one(em)
      an = 0.25_dp*(an + lam)
      anf = 0.25_dp*(anf + lam)
      xn = 0.25_dp*(xn + lam); yn = 0.25_dp*(yn + lam); zn = 0.25_dp*(zn + lam)
      pn = 0.25_dp*(pn + lam)
      f4 = 0.25_dp*f4
      f64 = f64/64.0_dp
    end do
    xd = (a0f - x)*f4/anf
    yd = (a0f - y)*f4/anf
    zd = -(xd + yd)
    e2 = xd*yd - zd*zd
    e3 = xd*yd*zd
    rf = (1.0_dp - e2/10.0_dp + e3/14.0_dp + e2*e2/24.0_dp - 3.0_dp*e2*e3/44.0_dp)/sqrt(anf)
    xd = (a0 - x)*f4/an
    yd = (a0 - y)*f4/an
    zd = (a0 - z)*f4/an
    pd = -0.5_dp*(xd + yd + zd)
    e2 = xd*yd + xd*zd + yd*zd - 3.0_dp*pd*pd
    e3 = xd*yd*zd + 2.0_dp*e2*pd + 4.0_dp*pd*pd*pd
    e4 = (2.0_dp*xd*yd*zd + e2*pd + 3.0_dp*pd*pd*pd)*pd
    e5 = xd*yd*zd*pd*pd
    rj = f4*(1.0_dp - 3.0_dp*e2/14.0_dp + e3/6.0_dp + 9.0_dp*e2*e2/88.0_dp - 3.0_dp*e4/22.0_dp &
             - 9.0_dp*e2*e3/52.0_dp + 3.0_dp*e5/26.0_dp)/(an*sqrt(an)) + 6.0_dp*s
  end subroutine carlson_rf_rj

  ! ------------------------------------------------------------------ complete integrals

  !> K(m) = int_0^{pi/2} dtheta / sqrt(1 - m sin^2 theta) = R_F(0, 1-m, 1); +Inf at m = 1.
  elemental real(dp) function elliptic_k(m)
    real(dp), intent(in) :: m
    elliptic_k = elliptic_k_mc(1.0_dp - m)
  end function elliptic_k

  !> K as a function of the complementary parameter mc = 1 - m.
  elemental real(dp) function elliptic_k_mc(mc)
    use, intrinsic :: ieee_arithmetic, only: ieee_positive_inf
    real(dp), intent(in) :: mc
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      elliptic_k_mc = nan_value()
    else if (mc == 0.0_dp) then
      elliptic_k_mc = ieee_value(0.0_dp, ieee_positive_inf)
    else
      elliptic_k_mc = carlson_rf(0.0_dp, mc, 1.0_dp)
    end if
  end function elliptic_k_mc

  !> E(m) = int_0^{pi/2} sqrt(1 - m sin^2 theta) dtheta = mc/3 (R_D(0,mc,1) + R_D(0,1,mc)),
  !> the second form of DLMF 19.25.1: a sum of positive terms, where R_F - m/3 R_D loses
  !> a factor K/E (8 at mc = 1e-6) to cancellation.
  elemental real(dp) function elliptic_e(m)
    real(dp), intent(in) :: m
    elliptic_e = elliptic_e_mc(1.0_dp - m)
  end function elliptic_e

  elemental real(dp) function elliptic_e_mc(mc)
    real(dp), intent(in) :: mc
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      elliptic_e_mc = nan_value()
    else if (mc == 0.0_dp) then
      elliptic_e_mc = 1.0_dp
    else
      elliptic_e_mc = mc/3.0_dp*(carlson_rd(0.0_dp, mc, 1.0_dp) + carlson_rd(0.0_dp, 1.0_dp, mc))
    end if
  end function elliptic_e_mc

  !> Pi(n|m) = int_0^{pi/2} dtheta / ((1 - n sin^2) sqrt(1 - m sin^2)), n < 1, m < 1.
  elemental real(dp) function elliptic_pi_complete(n, m)
    real(dp), intent(in) :: n, m
    elliptic_pi_complete = elliptic_pi_complete_mc(n, 1.0_dp - m)
  end function elliptic_pi_complete

  elemental real(dp) function elliptic_pi_complete_mc(n, mc)
    real(dp), intent(in) :: n, mc
    if (mc <= 0.0_dp .or. mc > 1.0_dp .or. n >= 1.0_dp) then
      elliptic_pi_complete_mc = nan_value()
    else
      elliptic_pi_complete_mc = carlson_rf(0.0_dp, mc, 1.0_dp) &
                                + n/3.0_dp*carlson_rj(0.0_dp, mc, 1.0_dp, 1.0_dp - n)
    end if
  end function elliptic_pi_complete_mc

  ! ------------------------------------------------------------------ incomplete integrals
  ! Any real phi: phi = phi_r + j pi with |phi_r| <= pi/2, and the integral over each half
  ! period pi is twice the complete one (the integrands are pi-periodic and even).

  !> Reduces phi to phi_r in [-pi/2, pi/2] and returns j with phi = phi_r + j pi.
  elemental subroutine reduce_amplitude(phi, phi_r, j)
    real(dp), intent(in) :: phi
    real(dp), intent(out) :: phi_r
    real(dp), intent(out) :: j
    j = anint(phi/pi)
    phi_r = phi - j*pi
  end subroutine reduce_amplitude

  !> F(phi|m) = int_0^phi dtheta / sqrt(1 - m sin^2 theta) (DLMF 19.2.4, 19.25.5).
  elemental real(dp) function elliptic_f(phi, m)
    real(dp), intent(in) :: phi, m
    elliptic_f = elliptic_f_mc(phi, 1.0_dp - m)
  end function elliptic_f

  elemental real(dp) function elliptic_f_mc(phi, mc)
    real(dp), intent(in) :: phi, mc
    real(dp) :: phi_r, s, c, j
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      elliptic_f_mc = nan_value()
      return
    end if
    call reduce_amplitude(phi, phi_r, j)
    s = sin(phi_r); c = cos(phi_r)
    if (s == 0.0_dp) then
      elliptic_f_mc = 0.0_dp
    else
      ! 1 - m s^2 written as c^2 + mc s^2: no cancellation as m -> 1.
      elliptic_f_mc = s*carlson_rf(c*c, c*c + mc*s*s, 1.0_dp)
    end if
    if (j /= 0.0_dp) elliptic_f_mc = elliptic_f_mc + 2.0_dp*j*elliptic_k_mc(mc)
  end function elliptic_f_mc

  !> E(phi|m) = int_0^phi sqrt(1 - m sin^2 theta) dtheta (DLMF 19.25.9).
  elemental real(dp) function elliptic_e_inc(phi, m)
    real(dp), intent(in) :: phi, m
    elliptic_e_inc = elliptic_e_inc_mc(phi, 1.0_dp - m)
  end function elliptic_e_inc

  elemental real(dp) function elliptic_e_inc_mc(phi, mc)
    real(dp), intent(in) :: phi, mc
    real(dp) :: phi_r, s, c, d2, m, j
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      elliptic_e_inc_mc = nan_value()
      return
    end if
    m = 1.0_dp - mc
    call reduce_amplitude(phi, phi_r, j)
    s = sin(phi_r); c = cos(phi_r)
    if (s == 0.0_dp) then
      elliptic_e_inc_mc = 0.0_dp
    else
      d2 = c*c + mc*s*s
      elliptic_e_inc_mc = s*carlson_rf(c*c, d2, 1.0_dp) - m/3.0_dp*s**3*carlson_rd(c*c, d2, 1.0_dp)
    end if
    if (j /= 0.0_dp) elliptic_e_inc_mc = elliptic_e_inc_mc + 2.0_dp*j*elliptic_e_mc(mc)
  end function elliptic_e_inc_mc

  !> Pi(n; phi|m) = int_0^phi dtheta / ((1 - n sin^2 theta) sqrt(1 - m sin^2 theta))
  !> (A&S 17.2.15, DLMF 19.25.14). Needs 1 - n sin^2 theta > 0 on the path: n sin^2 phi < 1
  !> for |phi| <= pi/2, n < 1 beyond; otherwise NaN (principal values not provided).
  elemental real(dp) function elliptic_pi(n, phi, m)
    real(dp), intent(in) :: n, phi, m
    elliptic_pi = elliptic_pi_mc(n, phi, 1.0_dp - m)
  end function elliptic_pi

  elemental real(dp) function elliptic_pi_mc(n, phi, mc)
    real(dp), intent(in) :: n, phi, mc
    real(dp) :: phi_r, s, c, d2, j
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      elliptic_pi_mc = nan_value()
      return
    end if
    call reduce_amplitude(phi, phi_r, j)
    s = sin(phi_r); c = cos(phi_r)
    if (j /= 0.0_dp .and. n >= 1.0_dp) then
      elliptic_pi_mc = nan_value()
      return
    end if
    if (s == 0.0_dp) then
      elliptic_pi_mc = 0.0_dp
    else
      d2 = c*c + mc*s*s
      elliptic_pi_mc = s*carlson_rf(c*c, d2, 1.0_dp) &
                       + n/3.0_dp*s**3*carlson_rj(c*c, d2, 1.0_dp, 1.0_dp - n*s*s)
    end if
    if (j /= 0.0_dp) elliptic_pi_mc = elliptic_pi_mc + 2.0_dp*j*elliptic_pi_complete_mc(n, mc)
  end function elliptic_pi_mc

  ! ------------------------------------------------------------------ Jacobi functions

  !> sn, cn, dn of u for parameter m (0 <= m <= 1). Exact limits: m = 0 gives sin, cos, 1;
  !> m = 1 gives tanh, sech, sech.
  elemental subroutine jacobi_sncndn(u, m, sn, cn, dn)
    real(dp), intent(in) :: u, m
    real(dp), intent(out) :: sn, cn, dn
    call jacobi_sncndn_mc(u, 1.0_dp - m, sn, cn, dn)
  end subroutine jacobi_sncndn

  !> sn, cn, dn from the complementary parameter mc = 1 - m. The argument is first reduced
  !> by the half period 2K (sn, cn change sign, dn does not), so |u_r| <= K.
  elemental subroutine jacobi_sncndn_mc(u, mc, sn, cn, dn)
    real(dp), intent(in) :: u, mc
    real(dp), intent(out) :: sn, cn, dn
    real(dp) :: u_r, j
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      sn = nan_value(); cn = sn; dn = sn
      return
    end if
    call reduce_half_period(u, mc, u_r, j)
    call jacobi_sncndn_core(u_r, mc, sn, cn, dn)
    if (mod(j, 2.0_dp) /= 0.0_dp) then
      sn = -sn
      cn = -cn
    end if
  end subroutine jacobi_sncndn_mc

  !> u = u_r + 2 j K(mc) with |u_r| <= K (no reduction at mc = 0, where K is infinite).
  elemental subroutine reduce_half_period(u, mc, u_r, j)
    real(dp), intent(in) :: u, mc
    real(dp), intent(out) :: u_r
    real(dp), intent(out) :: j
    real(dp) :: two_k
    if (mc == 0.0_dp) then
      u_r = u
      j = 0.0_dp
      return
    end if
    two_k = 2.0_dp*carlson_rf(0.0_dp, mc, 1.0_dp)
    j = anint(u/two_k)
    u_r = u - j*two_k
  end subroutine reduce_half_period

  !> Bulirsch's descending Landen (AGM) algorithm for sn, cn, dn WITHOUT argument reduction:
  !> for callers that reduce u themselves with a K they already hold (|u| <= K is where it
  !> is accurate to a few ulps; larger |u| loses accuracy as ulp(c u) grows).
  elemental subroutine jacobi_sncndn_core(u, mc, sn, cn, dn)
    real(dp), intent(in) :: u, mc
    real(dp), intent(out) :: sn, cn, dn
    real(dp) :: em(jacobi_agm_max_steps), en(jacobi_agm_max_steps), c
    integer :: l
    call jacobi_agm_table(mc, em, en, l, c)
    call jacobi_sncndn_table(u, mc, em, en, l, c, sn, cn, dn)
  end subroutine jacobi_sncndn_core

  !> The descending AGM sequence of Bulirsch's algorithm, which depends on mc only: a
  !> caller evaluating many u for one mc computes it once (free_rotor_t does).
  pure subroutine jacobi_agm_table(mc, em, en, l, c)
    real(dp), intent(in) :: mc
    real(dp), intent(out) :: em(jacobi_agm_max_steps), en(jacobi_agm_max_steps), c
    integer, intent(out) :: l
    real(dp) :: a, emc
    integer :: i
    em = 0.0_dp
    en = 0.0_dp
    c = 1.0_dp
    l = 0
    if (mc <= 0.0_dp) return
    emc = mc
    a = 1.0_dp
    l = jacobi_agm_max_steps
    do i = 1, jacobi_agm_max_steps
      em(i) = a
      emc = sqrt(emc)
      en(i) = emc
      c = 0.5_dp*(a + emc)
      if (abs(a - emc) <= agm_tolerance*a) then
        l = i
        exit
      end if
      emc = a*emc
      a = c
    end do
  end subroutine jacobi_agm_table

  !> sn, cn, dn of u (no reduction) from the AGM table of mc (jacobi_agm_table).
  pure subroutine jacobi_sncndn_table(u, mc, em, en, l, c, sn, cn, dn)
    real(dp), intent(in) :: u, mc, em(jacobi_agm_max_steps), en(jacobi_agm_max_steps), c
    integer, intent(in) :: l
    real(dp), intent(out) :: sn, cn, dn
    real(dp) :: a, b, cc
    integer :: i
    if (mc == 0.0_dp) then
      ! m = 1: sn = tanh, cn = dn = sech (asymptotic form where cosh would overflow).
      sn = tanh(u)
      if (abs(u) < sech_asymptotic) then
        cn = 1.0_dp/cosh(u)
      else
        cn = 2.0_dp*exp(-abs(u))
      end if
      dn = cn
      return
    end if
    dn = 1.0_dp
    sn = sin(c*u)
    cn = cos(c*u)
    if (sn /= 0.0_dp) then
      a = cn/sn
      cc = a*c
      do i = l, 1, -1
        b = em(i)
        a = cc*a
        cc = dn*cc
        dn = (en(i) + a)/(b + a)
        a = cc/b
      end do
      a = 1.0_dp/sqrt(cc*cc + 1.0_dp)
      sn = sign(a, sn)
      cn = cc*sn
    end if
  end subroutine jacobi_sncndn_table

  !> Amplitude am(u|m), unwrapped: am(u + 2K) = am(u) + pi, so it grows without bound
  !> with u (what the orientation integral over many periods needs).
  elemental real(dp) function jacobi_am(u, m)
    real(dp), intent(in) :: u, m
    jacobi_am = jacobi_am_mc(u, 1.0_dp - m)
  end function jacobi_am

  elemental real(dp) function jacobi_am_mc(u, mc)
    real(dp), intent(in) :: u, mc
    real(dp) :: u_r, sn, cn, dn, j
    if (mc < 0.0_dp .or. mc > 1.0_dp) then
      jacobi_am_mc = nan_value()
      return
    end if
    if (mc == 0.0_dp) then
      ! am(u|1) = gd(u) = 2 atan(tanh(u/2)), bounded by pi/2.
      jacobi_am_mc = 2.0_dp*atan(tanh(0.5_dp*u))
      return
    end if
    call reduce_half_period(u, mc, u_r, j)
    call jacobi_sncndn_core(u_r, mc, sn, cn, dn)
    ! |u_r| <= K so cn >= 0 and atan2 returns am(u_r) in [-pi/2, pi/2].
    jacobi_am_mc = atan2(sn, cn) + j*pi
  end function jacobi_am_mc

end module elliptic_functions
