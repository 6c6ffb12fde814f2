!> Exact torque-free rotation of a rigid body (between contacts): the state at any time
!> t0 + t in O(1) work, to round-off, at any step size (docs/rotation.md has the derivation).
!>
!> Body-frame angular momentum m(t) in Jacobi elliptic functions (Landau-Lifshitz, Mechanics
!> §37); orientation by the Euler-angle route of Landau §37 / Celledoni, Fassò, Säfström,
!> Zanna (SIAM J. Sci. Comput. 30 (2008) 2084): in a frame whose third axis is the constant
!> world angular momentum L, R(t) = R_z(phi(t)) R_x(theta(t)) R_z(psi(t)), where theta, psi
!> follow algebraically from m(t) and phi(t) is an elliptic integral of the third kind.
!>
!> Conventions: q rotates body(principal)-frame vectors into the world; the angular velocity
!> is given and returned in the WORLD frame; the principal moments may come in any order.
!> The returned q is continuous in t (same sign branch as q0 at t = 0), normalised.
module free_rotation_exact
  use kinds, only: dp
  use constants, only: pi, two_pi
  use error_status, only: error_t, ERR_INPUT
  use quaternion, only: quat_mul, quat_conj, quat_rotate, quat_rotate_inverse, quat_exp, &
                        quat_from_matrix
  use elliptic_functions, only: carlson_rf_rj, elliptic_f_mc, jacobi_agm_table, jacobi_sncndn_table, jacobi_agm_max_steps
  implicit none
  private
  public :: free_rotor_t, exact_rotate
  public :: ROTOR_STATIC, ROTOR_STEADY_SPIN, ROTOR_AXISYMMETRIC, ROTOR_ELLIPTIC, ROTOR_SEPARATRIX

  !> Which closed form the rotor uses.
  integer, parameter :: ROTOR_STATIC = 0        !< w = 0
  integer, parameter :: ROTOR_STEADY_SPIN = 1   !< sphere, or L along a principal axis
  integer, parameter :: ROTOR_AXISYMMETRIC = 2  !< two equal moments: regular precession
  integer, parameter :: ROTOR_ELLIPTIC = 3      !< three distinct moments, off the separatrix
  integer, parameter :: ROTOR_SEPARATRIX = 4    !< three distinct moments, L^2 = 2 E I_mid

  !> Moments closer than this (relative to the largest) are treated as equal: the closed
  !> forms for equal moments then differ from the exact motion by a relative frequency
  !> error of this size, far below the elliptic branch's near-degenerate rounding.
  real(dp), parameter :: equal_moment_tolerance = 16.0_dp*epsilon(1.0_dp)
  !> A body-frame L whose components off its largest principal axis are below this
  !> fraction of |L| spins steadily about that axis (the elliptic moduli would underflow).
  real(dp), parameter :: steady_spin_tolerance = 1.0e-100_dp

  type :: free_rotor_t
    integer :: kind = ROTOR_STATIC
    ! (explicit padding, set: a rotor travels and is compared across ranks as its words, which
    ! must hold no byte left as it happened to be)
    integer :: pad_kind = 0
    real(dp) :: q0(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]  !< orientation at t0
    real(dp) :: w0_world(3) = 0.0_dp                        !< world angular velocity at t0 [rad/s]
    real(dp) :: energy = 0.0_dp                             !< kinetic energy [J]
    real(dp) :: l_norm = 0.0_dp                             !< |L| [kg m^2/s]
    ! axisymmetric: q(t) = exp(t L/I_perp) q0 exp(nu t e_u)
    real(dp) :: l_world(3) = 0.0_dp     !< world angular momentum [kg m^2/s]
    real(dp) :: inv_i_perp = 0.0_dp     !< 1/I of the equal pair [1/(kg m^2)]
    real(dp) :: nu = 0.0_dp             !< body-frame precession rate about e_u [rad/s]
    real(dp) :: axis(3) = 0.0_dp        !< body-frame unit vector of the unique axis
    ! elliptic and separatrix, in the "permuted" principal frame (a, b, c): c the axis L
    ! circulates about, b the intermediate one, v_perm = C v_body with C a proper rotation.
    real(dp) :: q_c(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]    !< quaternion of C
    real(dp) :: q_pre(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]  !< L-frame to world, incl. phi(0)
    real(dp) :: inertia_p(3) = 1.0_dp    !< (I_a, I_b, I_c) [kg m^2]
    real(dp) :: amp(3) = 0.0_dp          !< m = (amp_a cn, amp_b sn, amp_c dn) [kg m^2/s]
    real(dp) :: lambda = 0.0_dp          !< tau = lambda t + tau0 [1/s]
    real(dp) :: tau0 = 0.0_dp
    real(dp) :: mc = 1.0_dp              !< complementary parameter 1 - k^2
    real(dp) :: two_k = 0.0_dp           !< half period 2K(m) of sn in tau
    real(dp) :: n_char = 0.0_dp          !< characteristic n <= 0 of the third-kind integral
    real(dp) :: pi_c = 0.0_dp            !< complete Pi(n|m)
    real(dp) :: g0 = 0.0_dp              !< G(tau0), G(tau) = int_0^tau du/(1 - n sn^2 u)
    real(dp) :: omega_c = 0.0_dp         !< |L|/I_c [rad/s]
    real(dp) :: kappa = 0.0_dp           !< |L| (1/I_a - 1/I_c)/lambda [rad]
    ! Bulirsch's AGM sequence for mc, computed once (evaluate then skips ~5 square roots)
    real(dp) :: agm_em(jacobi_agm_max_steps) = 0.0_dp
    real(dp) :: agm_en(jacobi_agm_max_steps) = 0.0_dp
    real(dp) :: agm_c = 1.0_dp
    integer :: agm_l = 0
    integer :: pad_agm = 0
  contains
    procedure :: init => rotor_init
    procedure :: evaluate => rotor_evaluate
  end type free_rotor_t

contains

  !> Prepares the closed-form motion from the principal moments [kg m^2] (any order, all
  !> > 0), the orientation q0 (unit, body to world) and the world angular velocity [rad/s].
  subroutine rotor_init(self, inertia, q0, w0_world, err)
    class(free_rotor_t), intent(out) :: self
    real(dp), intent(in) :: inertia(3), q0(4), w0_world(3)
    type(error_t), intent(inout), optional :: err
    real(dp) :: m_body(3), u(3), off, imax
    integer :: p, iu
    character(len=48) :: text

    self%q0 = q0/norm2(q0)
    self%w0_world = w0_world
    if (.not. all(inertia > 0.0_dp .and. inertia < huge(1.0_dp))) then
      if (present(err)) then
        write (text, '(3es12.4)') inertia
        call err%set(ERR_INPUT, 'free_rotation_exact: principal moments of inertia must be finite and > 0 '// &
                     '[kg m^2], got'//trim(text))
      end if
      self%kind = ROTOR_STATIC
      self%w0_world = 0.0_dp
      return
    end if
    m_body = inertia*quat_rotate_inverse(self%q0, w0_world)
    self%l_norm = norm2(m_body)
    self%energy = 0.5_dp*sum(m_body**2/inertia)
    if (self%l_norm == 0.0_dp) then
      self%kind = ROTOR_STATIC
      return
    end if
    u = m_body/self%l_norm
    imax = maxval(inertia)
    p = maxloc(abs(u), dim=1)
    off = sqrt(u(mod(p, 3) + 1)**2 + u(mod(p + 1, 3) + 1)**2)
    if (maxval(inertia) - minval(inertia) <= equal_moment_tolerance*imax .or. off <= steady_spin_tolerance) then
      ! Sphere (any w) or L along a principal axis: w is constant in body and world.
      self%kind = ROTOR_STEADY_SPIN
      return
    end if
    iu = 0
    if (abs(inertia(1) - inertia(2)) <= equal_moment_tolerance*imax) iu = 3
    if (abs(inertia(2) - inertia(3)) <= equal_moment_tolerance*imax) iu = 1
    if (abs(inertia(1) - inertia(3)) <= equal_moment_tolerance*imax) iu = 2
    if (iu /= 0) then
      call init_axisymmetric(self, inertia, m_body, iu)
    else
      call init_triaxial(self, inertia, u)
    end if
  end subroutine rotor_init

  subroutine init_axisymmetric(self, inertia, m_body, iu)
    type(free_rotor_t), intent(inout) :: self
    real(dp), intent(in) :: inertia(3), m_body(3)
    integer, intent(in) :: iu
    real(dp) :: i_perp
    self%kind = ROTOR_AXISYMMETRIC
    i_perp = 0.5_dp*(sum(inertia) - inertia(iu))
    self%inv_i_perp = 1.0_dp/i_perp
    self%axis = 0.0_dp
    self%axis(iu) = 1.0_dp
    self%l_world = quat_rotate(self%q0, m_body)
    self%nu = m_body(iu)*(1.0_dp/inertia(iu) - self%inv_i_perp)
  end subroutine init_axisymmetric

  !> Three distinct moments. u = unit body-frame angular momentum.
  subroutine init_triaxial(self, inertia, u)
    type(free_rotor_t), intent(inout) :: self
    real(dp), intent(in) :: inertia(3), u(3)
    real(dp) :: c(3, 3), s(3, 3), up(3), ia, ib, ic, ua, ub, uc, da, db, dc, alpha2, beta2, gamma2
    real(dp) :: alpha, beta, gamma, q_l(4), m_p(3), lam_sign, g, k_c, rj_c
    integer :: idx(3), tmp

    ! Sorted frame: rows of s are +-e_idx(i) with I ascending and det(s) = +1.
    idx = [1, 2, 3]
    if (inertia(idx(2)) < inertia(idx(1))) then
      tmp = idx(1); idx(1) = idx(2); idx(2) = tmp
    end if
    if (inertia(idx(3)) < inertia(idx(2))) then
      tmp = idx(2); idx(2) = idx(3); idx(3) = tmp
    end if
    if (inertia(idx(2)) < inertia(idx(1))) then
      tmp = idx(1); idx(1) = idx(2); idx(2) = tmp
    end if
    s = 0.0_dp
    s(1, idx(1)) = 1.0_dp
    s(2, idx(2)) = 1.0_dp
    s(3, idx(3)) = 1.0_dp
    if (det3(s) < 0.0_dp) s(2, :) = -s(2, :)

    ! Which side of the separatrix: D_b = L^2 - 2 E I_mid (over L^2), summed term by term
    ! from the body components so only the inherent cancellation remains.
    db = u(idx(1))**2*(inertia(idx(1)) - inertia(idx(2)))/inertia(idx(1)) &
         + u(idx(3))**2*(inertia(idx(3)) - inertia(idx(2)))/inertia(idx(3))
    if (db >= 0.0_dp) then
      ! L circulates about the largest axis: (a, b, c) = sorted (1, 2, 3).
      c = s
      self%inertia_p = [inertia(idx(1)), inertia(idx(2)), inertia(idx(3))]
    else
      ! L circulates about the smallest axis: (a, b, c) = (3, -2, 1), still right-handed.
      c(1, :) = s(3, :)
      c(2, :) = -s(2, :)
      c(3, :) = s(1, :)
      self%inertia_p = [inertia(idx(3)), inertia(idx(2)), inertia(idx(1))]
    end if
    self%q_c = quat_from_matrix(c)
    up = matmul(c, u)
    ia = self%inertia_p(1); ib = self%inertia_p(2); ic = self%inertia_p(3)
    ua = up(1); ub = up(2); uc = up(3)
    ! D_x = L^2 - 2 E I_x (over L^2); D_a and D_c are sums of same-signed terms.
    da = ub**2*(ib - ia)/ib + uc**2*(ic - ia)/ic
    dc = ua**2*(ia - ic)/ia + ub**2*(ib - ic)/ib
    db = ua**2*(ia - ib)/ia + uc**2*(ic - ib)/ic
    ! Amplitudes of m/|L| = (alpha cn, beta sn, gamma dn), each a sum of positive terms.
    alpha2 = ua**2 + ub**2*ia*(ic - ib)/(ib*(ic - ia))
    beta2 = ub**2 + ua**2*ib*(ic - ia)/(ia*(ic - ib))
    gamma2 = uc**2 + ub**2*ic*(ib - ia)/(ib*(ic - ia))
    alpha = sqrt(alpha2)
    beta = sqrt(beta2)
    gamma = sign(sqrt(gamma2), uc)
    ! 1 - k^2 = D_b (I_c - I_a) / (D_a (I_c - I_b)) (k^2 = D_c (I_a - I_b)/(D_a (I_c - I_b))).
    self%mc = min(1.0_dp, max(0.0_dp, db*(ic - ia)/(da*(ic - ib))))
    self%n_char = ic*(ia - ib)/(ia*(ic - ib))
    self%omega_c = self%l_norm/ic
    if (self%mc > 0.0_dp) then
      self%kind = ROTOR_ELLIPTIC
    else
      self%kind = ROTOR_SEPARATRIX
      ! On the separatrix cn = sech > 0, so m_a keeps the sign it starts with.
      alpha = sign(alpha, ua)
    end if
    ! alpha lambda = beta gamma (1/I_b - 1/I_c) fixes the sign; lambda^2 = D_a (I_c - I_b)/(I_a I_b I_c).
    lam_sign = sign(1.0_dp, gamma)*sign(1.0_dp, alpha)*sign(1.0_dp, ic - ib)
    self%lambda = lam_sign*self%l_norm*sqrt(da*(ic - ib)/(ia*ib*ic))
    self%amp = self%l_norm*[alpha, beta, gamma]
    self%kappa = self%l_norm*(1.0_dp/ia - 1.0_dp/ic)/self%lambda
    if (self%kind == ROTOR_ELLIPTIC) then
      ! K = R_F(0, mc, 1) and Pi(n|m) = K + n/3 R_J(0, mc, 1, 1 - n) (DLMF 19.25.1-2) in one loop.
      call carlson_rf_rj(0.0_dp, self%mc, 1.0_dp, 1.0_dp - self%n_char, k_c, rj_c)
      self%two_k = 2.0_dp*k_c
      self%pi_c = k_c + self%n_char/3.0_dp*rj_c
      call jacobi_agm_table(self%mc, self%agm_em, self%agm_en, self%agm_l, self%agm_c)
      ! sn(tau0) = ub/beta, cn(tau0) = ua/alpha: tau0 = F(am0|m).
      self%tau0 = elliptic_f_mc(atan2(ub/beta, ua/alpha), self%mc)
    else
      ! sinh(tau0) = sn/cn = (ub/beta)/(ua/alpha).
      self%tau0 = asinh((ub/beta)/(ua/alpha))
    end if
    call local_state(self, 0.0_dp, q_l, m_p, g, at_start=.true.)
    self%g0 = g
    ! q(t) = q_pre q_L(t) q_c with q(0) = q0 fixes q_pre (the rotation taking the L frame
    ! into the world, precession phase at t0 included).
    self%q_pre = quat_mul(quat_mul(self%q0, quat_conj(self%q_c)), quat_conj(q_l))
  end subroutine init_triaxial

  pure real(dp) function det3(a)
    real(dp), intent(in) :: a(3, 3)
    det3 = a(1, 1)*(a(2, 2)*a(3, 3) - a(2, 3)*a(3, 2)) - a(1, 2)*(a(2, 1)*a(3, 3) - a(2, 3)*a(3, 1)) &
           + a(1, 3)*(a(2, 1)*a(3, 2) - a(2, 2)*a(3, 1))
  end function det3

  !> Triaxial case: L-frame orientation q_l (permuted body frame to L frame, phi(0) = 0) and
  !> permuted-frame angular momentum m_p at t; g = G(tau) is returned for the set-up, which
  !> passes at_start (t = 0, phi = 0 before g0 is known).
  pure subroutine local_state(self, t, q_l, m_p, g, at_start)
    type(free_rotor_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: q_l(4), m_p(3), g
    logical, intent(in), optional :: at_start
    real(dp) :: tau, j, u, sn, cn, dn, amp, phi, psi, cos_t, sin_t, ch, sh, sp, sm, nn, p, flip, rf, rj
    tau = self%lambda*t + self%tau0
    if (self%kind == ROTOR_ELLIPTIC) then
      ! tau = u + 2 j K, |u| <= K; over each half period G grows by 2 Pi(n|m).
      j = anint(tau/self%two_k)
      u = tau - j*self%two_k
      call jacobi_sncndn_table(u, self%mc, self%agm_em, self%agm_en, self%agm_l, self%agm_c, sn, cn, dn)
      amp = atan2(sn, cn)
      g = 2.0_dp*j*self%pi_c
      if (sn /= 0.0_dp) then
        ! Pi(n; am u|m) = s R_F(c^2, dn^2, 1) + n/3 s^3 R_J(c^2, dn^2, 1, 1 - n s^2), DLMF 19.25.14
        p = 1.0_dp - self%n_char*sn*sn
        call carlson_rf_rj(cn*cn, dn*dn, 1.0_dp, p, rf, rj)
        g = g + sn*rf + self%n_char/3.0_dp*sn**3*rj
      end if
      if (mod(j, 2.0_dp) /= 0.0_dp) then
        sn = -sn
        cn = -cn
      end if
      amp = amp + j*pi
    else
      ! k = 1: sn = tanh, cn = dn = sech, and with N = -n
      ! G(tau) = (tau + sqrt(N) atan(sqrt(N) tanh tau))/(1 + N).
      sn = tanh(tau)
      if (abs(tau) < 40.0_dp) then
        cn = 1.0_dp/cosh(tau)
      else
        cn = 2.0_dp*exp(-abs(tau))
      end if
      dn = cn
      nn = -self%n_char
      g = (tau + sqrt(nn)*atan(sqrt(nn)*sn))/(1.0_dp + nn)
      amp = 0.0_dp
    end if
    m_p = self%amp*[cn, sn, dn]
    ! phi reduced by 4 pi (q_l is 4 pi-periodic in phi): any rounding of the reduction is
    ! then common to phi + psi and phi - psi, i.e. a rotation about L only, so the world L
    ! stays fixed to round-off even when phi ~ 1e7 rad (t ~ 1e6 s).
    phi = 0.0_dp
    if (present(at_start)) then
      if (at_start) phi = 0.0_dp
    end if
    if (.not. present(at_start)) then
      phi = self%omega_c*t + self%kappa*(g - self%g0)
      phi = phi - 2.0_dp*two_pi*anint(phi/(2.0_dp*two_pi))
    end if
    ! m_p/|L| = (sin theta sin psi, sin theta cos psi, cos theta).
    psi = atan2(m_p(1), m_p(2))
    flip = 1.0_dp
    if (self%kind == ROTOR_ELLIPTIC) then
      ! The continuous psi stays within pi/2 of pi/2 - am(tau) (same quadrant as (cn, sn));
      ! psi_cont = psi + 2 pi j_psi, and a shift of psi by 2 pi flips the sign of q_l. This
      ! keeps q continuous in t over any number of periods without adding a large psi.
      if (mod(anint((0.5_dp*pi - amp - psi)/two_pi), 2.0_dp) /= 0.0_dp) flip = -1.0_dp
    end if
    cos_t = m_p(3)/self%l_norm
    sin_t = sqrt(m_p(1)**2 + m_p(2)**2)/self%l_norm
    ! Half angles of theta without cancellation at either pole.
    if (cos_t >= 0.0_dp) then
      ch = sqrt(0.5_dp*(1.0_dp + cos_t))
      sh = 0.5_dp*sin_t/ch
    else
      sh = sqrt(0.5_dp*(1.0_dp - cos_t))
      ch = 0.5_dp*sin_t/sh
    end if
    sp = 0.5_dp*(phi + psi)
    sm = 0.5_dp*(phi - psi)
    ! R_z(phi) R_x(theta) R_z(psi) as a quaternion.
    q_l = flip*[ch*cos(sp), sh*cos(sm), sh*sin(sm), ch*sin(sp)]
  end subroutine local_state

  !> Orientation q (body to world, unit) and world angular velocity [rad/s] at t0 + t [s].
  pure subroutine rotor_evaluate(self, t, q, w_world)
    class(free_rotor_t), intent(in) :: self
    real(dp), intent(in) :: t
    real(dp), intent(out) :: q(4), w_world(3)
    real(dp) :: q_l(4), q_pl(4), m_p(3), g
    select case (self%kind)
    case (ROTOR_STATIC)
      q = self%q0
      w_world = self%w0_world
    case (ROTOR_STEADY_SPIN)
      q = quat_mul(quat_exp(t*self%w0_world), self%q0)
      q = q/norm2(q)
      w_world = self%w0_world
    case (ROTOR_AXISYMMETRIC)
      q = quat_mul(quat_mul(quat_exp(t*self%inv_i_perp*self%l_world), self%q0), quat_exp(t*self%nu*self%axis))
      q = q/norm2(q)
      w_world = self%inv_i_perp*self%l_world + self%nu*quat_rotate(q, self%axis)
    case default
      call local_state(self, t, q_l, m_p, g)
      q_pl = quat_mul(self%q_pre, q_l)
      q_pl = q_pl/norm2(q_pl)
      w_world = quat_rotate(q_pl, m_p/self%inertia_p)
      q = quat_mul(q_pl, self%q_c)
      q = q/norm2(q)
    end select
  end subroutine rotor_evaluate

  !> Advances (q, w_world) in place by h [s] of torque-free motion with principal moments
  !> inertia [kg m^2] (any order).
  subroutine exact_rotate(q, w_world, inertia, h, err)
    real(dp), intent(inout) :: q(4), w_world(3)
    real(dp), intent(in) :: inertia(3), h
    type(error_t), intent(inout), optional :: err
    type(free_rotor_t) :: rotor
    call rotor%init(inertia, q, w_world, err)
    if (present(err)) then
      if (err%failed()) return
    end if
    call rotor%evaluate(h, q, w_world)
  end subroutine exact_rotate

end module free_rotation_exact
