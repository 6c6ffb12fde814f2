!> Exact torque-free rotation (free_rotation_exact) against the DOP853 reference csv, an
!> independent RK4 integration of the Euler equations, the closed forms of the degenerate
!> cases, and the invariants (energy, |L|, world L), composition and time reversal.
program test_free_rotation_exact
  use kinds, only: dp
  use constants, only: pi
  use quaternion, only: quat_mul, quat_exp, quat_rotate, quat_rotate_inverse, quat_normalize
  use error_status, only: error_t
  use free_rotation_exact
  use assertions
  implicit none
  real(dp), parameter :: eps = epsilon(1.0_dp)
  real(dp), parameter :: i123(3) = [1.0_dp, 2.0_dp, 3.0_dp]
  real(dp), parameter :: q_id(4) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
  real(dp), allocatable :: ref(:, :)
  type(free_rotor_t) :: rotor, rotor2
  type(error_t) :: err
  real(dp) :: q(4), w(3), q1(4), w1(3), q2(4), w2(3), q0(4), w0(3), max_q, max_w, inertia(3)
  real(dp) :: t_flip(4), t_ref(4), dq, dw
  integer :: i, k, nflip

  call read_reference(test_data_path('free_rotation_I123.csv'), ref)
  call check(size(ref, 2) == 2001, 'reference csv has 2001 samples')

  ! ---- reference csv (I = (1,2,3), w0 = (0.01, 5, 0.01), q0 = 1), DOP853 at 1e-13 whose
  ! stated accuracy is 3.2e-9 (difference to the 1e-12 run; Radau agrees to 1e-9). Tolerance
  ! 1e-8 on every q and body-w component: 3x the reference's own error, while a wrong
  ! period, phase or precession rate would be off by >1e-3 within the 20 s.
  call rotor%init(i123, q_id, ref(2:4, 1))
  call check(rotor%kind == ROTOR_ELLIPTIC, 'reference case is the elliptic branch')
  max_q = 0.0_dp; max_w = 0.0_dp
  do k = 1, size(ref, 2)
    ! Every sample as ONE step from t = 0 (the last one is the single 20 s step).
    call rotor%evaluate(ref(1, k), q, w)
    call accumulate(q, w, ref(:, k), max_q, max_w)
  end do
  call check_close(max_q, 0.0_dp, 0.0_dp, 'single steps from 0 to each sample: q vs csv', atol=1.0e-8_dp)
  call check_close(max_w, 0.0_dp, 0.0_dp, 'single steps from 0 to each sample: body w vs csv', atol=1.0e-8_dp)
  write (*, '(a,2es10.2)') 'csv, single steps: max |dq|, |dw| = ', max_q, max_w
  call rotor%evaluate(20.0_dp, q, w)
  dq = 0.0_dp; dw = 0.0_dp
  call accumulate(q, w, ref(:, size(ref, 2)), dq, dw)
  call check(max(dq, dw) < 1.0e-8_dp, 'one step of 20 s matches the csv end state')
  ! 2000 chained steps of 1e-2 s through exact_rotate (re-initialised every step). Each
  ! restart is exact to ~1e-13 (measured one-step defect 8e-14), but 8e-6 from the
  ! separatrix, 1 - k^2 comes from D_b = L^2 - 2 E I_2, a difference of O(1) terms equal
  ! to 2e-6 L^2: a 1e-14 state error moves 1 - k^2, hence K and the flip phase, by ~1e-9
  ! relative per restart. That conditioning (any integrator restarted from rounded states
  ! has it) makes the chained error a random walk of roundings: measured 1.1e-8 and 3.3e-8
  ! in w (9e-10 and 2.5e-9 in q) for two versions of the code differing only in rounding.
  ! Tolerance 1e-7 on w and 2e-8 on q (3x and 8x the larger measurement).
  q = q_id; w = quat_rotate(q_id, ref(2:4, 1))
  max_q = 0.0_dp; max_w = 0.0_dp
  do k = 2, size(ref, 2)
    call exact_rotate(q, w, i123, ref(1, k) - ref(1, k - 1))
    call accumulate(q, w, ref(:, k), max_q, max_w)
  end do
  call check_close(max_q, 0.0_dp, 0.0_dp, '2000 steps of 1e-2 s: q vs csv', atol=2.0e-8_dp)
  call check_close(max_w, 0.0_dp, 0.0_dp, '2000 steps of 1e-2 s: body w vs csv', atol=1.0e-7_dp)
  write (*, '(a,2es10.2)') 'csv, 2000 steps: max |dq|, |dw| = ', max_q, max_w

  ! ---- flips of the intermediate component w_y: zero crossings found by bisection on the
  ! exact solution against the csv's (linearly interpolated between 0.01 s samples; that
  ! interpolation is good to |w_y''| dt^2/(8|w_y'|) < 1e-5 s here). Also against the times
  ! given in the reference README (3 decimals, so 5e-4 s).
  call rotor%init(i123, q_id, ref(2:4, 1))
  nflip = 0
  do k = 2, size(ref, 2)
    if (ref(3, k - 1)*ref(3, k) < 0.0_dp .and. nflip < 4) then
      nflip = nflip + 1
      t_ref(nflip) = ref(1, k - 1) - ref(3, k - 1)*(ref(1, k) - ref(1, k - 1))/(ref(3, k) - ref(3, k - 1))
      t_flip(nflip) = wy_zero(rotor, ref(1, k - 1), ref(1, k))
    end if
  end do
  call check(nflip == 4, 'four w_y sign changes in the csv')
  call check_close_array(t_flip, t_ref, 0.0_dp, 'w_y flip times vs csv', atol=1.0e-5_dp)
  ! The README's first time 2.742 is 9.3e-4 s after the csv's own crossing (2.74107);
  ! the others agree to 1.5e-4: the README rounds loosely, so 1e-3 s against it.
  call check_close_array(t_flip, [2.742_dp, 7.767_dp, 12.793_dp, 17.819_dp], 0.0_dp, &
                         'w_y flip times vs README', atol=1.0e-3_dp)
  ! Flips are a half period 2K/|lambda| apart (dn-cn-sn solution): 2 ulps of the bisection.
  call check_close(t_flip(3) - t_flip(2), rotor%two_k/abs(rotor%lambda), 0.0_dp, 'flip spacing = 2K/lambda', &
                   atol=1.0e-12_dp)
  write (*, '(a,4f16.12)') 'flip times: ', t_flip

  ! ---- invariants per evaluation: energy, |L| and the world vector L from the returned
  ! (q, w_world) against t = 0. Through that output they can only be seen to ~20 ulps: the
  ! evaluation's w_world = R(q) I^-1 m and this check's R(q)^T w_world each round up to ~4
  ! ulps of |w| per component, and E, |L| are dominated here by w_y = 5 (relative error
  ! doubled in the square). Tolerance 24 eps = 5.3e-15 (measured <= 3.7e-15 on this case,
  ! < 2e-15 on the others, which are checked to 12 eps). The world L is fixed whatever
  ! the precession angle is (q_pre e3 is its direction), so it holds at huge t as well.
  call invariants(rotor, i123, q_id, ref(2:4, 1), 24.0_dp*eps, [(0.37_dp*k, k=-60, 60)], 'reference case')
  ! Huge times: phase accuracy is then bounded by ulp(lambda t) but the invariants are not.
  call invariants(rotor, i123, q_id, ref(2:4, 1), 24.0_dp*eps, [1.0e6_dp, -1.0e6_dp, 3.3e5_dp, 1.0e7_dp], 'huge t')

  ! ---- composition h1 then h2 = one step h1 + h2, and reversal h then -h. Round-off is
  ! amplified by the flow's sensitivity (here up to ~1e3 over 20 s next to the separatrix,
  ! measured 2e-13): 1e-11 absolute on q and w.
  call composition(i123, q_id, ref(2:4, 1), 7.3_dp, 11.9_dp, 5.0e-11_dp, 'reference case')
  q0 = quat_normalize([0.3_dp, -0.5_dp, 0.7_dp, 0.2_dp])
  w0 = [1.3_dp, -0.7_dp, 2.1_dp]
  call composition([2.0_dp, 0.7_dp, 1.3_dp], q0, w0, 3.1_dp, -1.7_dp, 1.0e-12_dp, 'unsorted moments')
  call composition([2.0_dp, 0.7_dp, 1.3_dp], q0, w0, 40.0_dp, -40.0_dp, 1.0e-12_dp, 'reversal')

  ! ---- against an independent RK4 of the Euler equations + quaternion kinematics
  ! (dt = 1e-4 s: RK4 global error ~1e-13 for |w| < 5 over these times). Tolerance 1e-10:
  ! RK4 error times the growth of perturbations (largest near the separatrix).
  ! Both sides of the separatrix, moments in any order, general q0:
  call versus_rk4([2.0_dp, 0.7_dp, 1.3_dp], q0, w0, 3.0_dp, 1.0e-10_dp, 'three moments unsorted')
  call rotor%init([2.0_dp, 0.7_dp, 1.3_dp], q0, w0)
  call check(rotor%kind == ROTOR_ELLIPTIC, 'unsorted case is elliptic')
  call versus_rk4([3.0_dp, 1.0_dp, 2.0_dp], q0, quat_rotate(q0, [4.0_dp, 0.3_dp, 0.2_dp]), 3.0_dp, 1.0e-10_dp, &
                  'circulating about the largest axis')
  call versus_rk4([3.0_dp, 1.0_dp, 2.0_dp], q0, quat_rotate(q0, [0.2_dp, 4.0_dp, 0.3_dp]), 3.0_dp, 1.0e-10_dp, &
                  'circulating about the smallest axis')
  call versus_rk4([1.0_dp, 2.0_dp, 3.0_dp], q0, quat_rotate(q0, [0.2_dp, -2.0_dp, 0.3_dp]), 3.0_dp, 1.0e-10_dp, &
                  'sorted, other side')

  ! ---- near the separatrix (1 - k^2 from 1e-4 down to ~1e-15) and exactly on it.
  ! I = (1, 1.5, 3) and m = (3, 1.5 w_y, 3) gives L^2 - 2 E I_2 = 0 exactly in floating point.
  inertia = [1.0_dp, 1.5_dp, 3.0_dp]
  call rotor%init(inertia, q_id, [3.0_dp, 2.0_dp, 1.0_dp])
  call check(rotor%kind == ROTOR_SEPARATRIX, 'exact separatrix selects the sech/tanh branch')
  call versus_rk4(inertia, q_id, [3.0_dp, 2.0_dp, 1.0_dp], 3.0_dp, 1.0e-10_dp, 'on the separatrix')
  call versus_rk4(inertia, q0, quat_rotate(q0, [3.0_dp, 2.0_dp, 1.0_dp]), 3.0_dp, 1.0e-10_dp, 'on the separatrix, q0')
  call invariants(rotor, inertia, q_id, [3.0_dp, 2.0_dp, 1.0_dp], 12.0_dp*eps, [0.5_dp, 3.0_dp, 50.0_dp, 1.0e6_dp], 'separatrix')
  call composition(inertia, q_id, [3.0_dp, 2.0_dp, 1.0_dp], 1.1_dp, 2.3_dp, 1.0e-11_dp, 'separatrix')
  ! Approaches steady spin about the intermediate axis: w -> +-w_y e_y in the body.
  call rotor%evaluate(60.0_dp, q, w)
  w1 = quat_rotate_inverse(q, w)
  call check(abs(w1(1)) + abs(w1(3)) < 1.0e-12_dp*norm2(w1), 'separatrix tends to intermediate-axis spin')
  do i = 1, 4
    ! Perturb w_z: mc grows like the perturbation (1e-15 .. 1e-3).
    w0 = [3.0_dp, 2.0_dp, 1.0_dp + 10.0_dp**(-3*i - 3)]
    call rotor%init(inertia, q_id, w0)
    write (*, '(a,es9.1,a,i0)') 'near separatrix: 1 - k^2 = ', rotor%mc, ', branch ', rotor%kind
    call check(rotor%kind == ROTOR_ELLIPTIC .and. rotor%mc > 0.0_dp .and. rotor%mc < 1.0e-2_dp, &
               'near-separatrix case is elliptic with small 1 - k^2')
    call versus_rk4(inertia, q_id, w0, 3.0_dp, 1.0e-10_dp, 'near the separatrix')
    call invariants(rotor, inertia, q_id, w0, 12.0_dp*eps, [0.5_dp, 3.0_dp, 50.0_dp, 1.0e6_dp], 'near separatrix')
    call composition(inertia, q_id, w0, 1.1_dp, 2.3_dp, 1.0e-11_dp, 'near separatrix')
  end do

  ! Through the flips, against a 40-digit Taylor integration (tools/reference/
  ! free_rotation_near_separatrix.py) from the same doubles. Near the separatrix the
  ! period is K ~ ln(4/sqrt(1-k^2)) and 1 - k^2 comes from D_b = L^2 - 2 E I_2, O(1)
  ! terms cancelling to ~(1-k^2) L^2: the rounding of m = I w alone moves it by
  ! ~eps/(1-k^2) relative, so the flip phase, and the state after a flip, carry an error
  ! ~eps/(1-k^2) (measured 7.5e-10 at 1 - k^2 = 1.3e-6, 9.6e-8 at 1.3e-9). Tolerance
  ! 4e-15/(1 - k^2) on q and m (3e-9 and 3e-6): graceful, and the check fails for any
  ! error in the period or phase formulas (which would be O(1) after a flip).
  call read_near_separatrix(test_data_path('free_rotation_near_separatrix.csv'))

  ! ---- axisymmetric: regular precession. Closed form written independently here:
  ! body w precesses about e_3 at Omega = (I_1 - I_3)/I_1 w_3 ... checked through RK4, and
  ! the world w stays on a cone about L: w . L constant (= 2E) and |w| constant.
  inertia = [2.0_dp, 2.0_dp, 3.0_dp]
  call rotor%init(inertia, q0, [0.5_dp, 1.0_dp, 2.0_dp])
  call check(rotor%kind == ROTOR_AXISYMMETRIC, 'two equal moments select regular precession')
  call versus_rk4(inertia, q0, [0.5_dp, 1.0_dp, 2.0_dp], 3.0_dp, 1.0e-10_dp, 'axisymmetric oblate')
  call versus_rk4([1.0_dp, 4.0_dp, 4.0_dp], q0, [0.5_dp, 1.0_dp, 2.0_dp], 3.0_dp, 1.0e-10_dp, 'axisymmetric prolate')
  call versus_rk4([4.0_dp, 1.0_dp, 4.0_dp], q0, [0.5_dp, 1.0_dp, 2.0_dp], 3.0_dp, 1.0e-10_dp, 'axisymmetric, axis 2')
  call invariants(rotor, inertia, q0, [0.5_dp, 1.0_dp, 2.0_dp], 12.0_dp*eps, [0.5_dp, 3.0_dp, 1.0e6_dp], 'axisymmetric')
  ! The body-frame precession rate in closed form: w_body(t) = Rz(Omega t) w_body(0) with
  ! Omega = (I3 - I1)/I1 w3 (Landau §33); tolerance 1e-13 (a few ulps of Omega t = 3).
  call rotor%evaluate(3.0_dp, q, w)
  w1 = quat_rotate_inverse(q, w)
  w2 = quat_rotate_inverse(q0, [0.5_dp, 1.0_dp, 2.0_dp])
  w2 = quat_rotate(quat_exp([0.0_dp, 0.0_dp, (3.0_dp - 2.0_dp)/2.0_dp*w2(3)*3.0_dp]), w2)
  call check_close_array(w1, w2, 0.0_dp, 'axisymmetric body-frame precession', atol=1.0e-13_dp)
  ! Nearly axisymmetric goes through the elliptic branch and must join the closed form:
  ! moments 1e-9 apart change the motion by ~1e-9 relative over these times.
  call rotor%init([2.0_dp, 2.0_dp + 1.0e-9_dp, 3.0_dp], q0, [0.5_dp, 1.0_dp, 2.0_dp])
  call rotor2%init(inertia, q0, [0.5_dp, 1.0_dp, 2.0_dp])
  call check(rotor%kind == ROTOR_ELLIPTIC, 'nearly axisymmetric is elliptic')
  call rotor%evaluate(3.0_dp, q1, w1)
  call rotor2%evaluate(3.0_dp, q2, w2)
  call check_close_array([q1, w1], [q2, w2], 0.0_dp, 'nearly axisymmetric joins regular precession', atol=1.0e-8_dp)

  ! ---- sphere: w constant, q = exp(t w) q0 (same formula, so round-off only: 4 ulps).
  call rotor%init([2.0_dp, 2.0_dp, 2.0_dp], q0, [0.5_dp, 1.0_dp, 2.0_dp])
  call check(rotor%kind == ROTOR_STEADY_SPIN, 'sphere spins steadily')
  call rotor%evaluate(1.7_dp, q, w)
  call check_close_array(w, [0.5_dp, 1.0_dp, 2.0_dp], 0.0_dp, 'sphere keeps w')
  call check_close_array(q, quat_mul(quat_exp(1.7_dp*[0.5_dp, 1.0_dp, 2.0_dp]), q0), 0.0_dp, 'sphere q = exp(t w) q0', &
                         atol=4.0_dp*eps)
  call versus_rk4([2.0_dp, 2.0_dp, 2.0_dp], q0, [0.5_dp, 1.0_dp, 2.0_dp], 3.0_dp, 1.0e-10_dp, 'sphere')
  ! ---- spin exactly about each principal axis (also the unstable intermediate one).
  ! With q0 = 1 the axis is exact; with a general q0 the rotated w is off the axis by
  ! round-off and the elliptic branch must still agree with RK4.
  do i = 1, 3
    w1 = 0.0_dp
    w1(i) = 3.0_dp
    call rotor%init([1.0_dp, 2.0_dp, 3.0_dp], q_id, w1)
    call check(rotor%kind == ROTOR_STEADY_SPIN, 'principal-axis spin is steady')
    call rotor%evaluate(25.0_dp, q, w)
    call check_close_array(w, w1, 0.0_dp, 'principal-axis spin keeps w exactly', atol=0.0_dp)
    call check_close(abs(q(1 + i)), abs(sin(0.5_dp*25.0_dp*3.0_dp)), 0.0_dp, 'principal-axis spin angle', &
                     atol=1.0e-14_dp)
    w1 = quat_rotate(q0, w1)
    call versus_rk4([1.0_dp, 2.0_dp, 3.0_dp], q0, w1, 2.0_dp, 1.0e-10_dp, 'principal-axis spin, general q0')
  end do
  ! ---- w = 0: nothing moves.
  call rotor%init(i123, q0, [0.0_dp, 0.0_dp, 0.0_dp])
  call check(rotor%kind == ROTOR_STATIC, 'w = 0 is static')
  call rotor%evaluate(1.0e3_dp, q, w)
  call check_close_array([q, w], [q0, 0.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'w = 0 keeps q0')
  ! ---- bad moments are an input error, not a crash.
  call rotor%init([1.0_dp, 0.0_dp, 2.0_dp], q0, w0, err)
  call check_error(err%code, err%message, [character(len=20) :: 'free_rotation_exact', 'moments'], &
                   'zero moment of inertia is rejected')

  call test_finish()

contains

  subroutine read_reference(path, data)
    character(len=*), intent(in) :: path
    real(dp), allocatable, intent(out) :: data(:, :)
    character(len=512) :: line
    real(dp) :: row(8)
    integer :: unit, ios, n
    allocate (data(8, 4000))
    n = 0
    open (newunit=unit, file=path, status='old', action='read')
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:1) == '#' .or. len_trim(line) == 0) cycle
      read (line, *) row
      n = n + 1
      data(:, n) = row
    end do
    close (unit)
    data = data(:, 1:n)
  end subroutine read_reference

  subroutine read_near_separatrix(path)
    character(len=*), intent(in) :: path
    character(len=512) :: line
    real(dp) :: row(9), q(4), w(3), dq, dm, inertia(3)
    integer :: unit, ios, n
    type(free_rotor_t) :: r
    inertia = [1.0_dp, 1.5_dp, 3.0_dp]
    n = 0
    open (newunit=unit, file=path, status='old', action='read')
    do
      read (unit, '(a)', iostat=ios) line
      if (ios /= 0) exit
      if (line(1:1) == '#' .or. len_trim(line) == 0) cycle
      read (line, *) row
      n = n + 1
      call r%init(inertia, q_id, [3.0_dp, 2.0_dp, 1.0_dp + 10.0_dp**(-nint(row(1)))])
      call r%evaluate(row(2), q, w)
      dq = min(maxval(abs(q - row(3:6))), maxval(abs(q + row(3:6))))
      dm = maxval(abs(inertia*quat_rotate_inverse(q, w) - row(7:9)))
      call check_close(max(dq, dm), 0.0_dp, 0.0_dp, 'near separatrix vs 40-digit reference', atol=4.0e-15_dp/r%mc)
      write (*, '(a,es9.1,a,f5.1,a,2es10.2)') 'near separatrix vs mpmath: 1 - k^2 =', r%mc, ' t =', row(2), &
        ': dq, dm =', dq, dm
    end do
    close (unit)
    call check(n == 8, 'eight near-separatrix reference states')
  end subroutine read_near_separatrix

  !> Largest component differences of q (either sign) and body-frame w to a csv row.
  subroutine accumulate(q, w, row, max_q, max_w)
    real(dp), intent(in) :: q(4), w(3), row(8)
    real(dp), intent(inout) :: max_q, max_w
    max_q = max(max_q, min(maxval(abs(q - row(5:8))), maxval(abs(q + row(5:8)))))
    max_w = max(max_w, maxval(abs(quat_rotate_inverse(q, w) - row(2:4))))
  end subroutine accumulate

  !> Zero of the body-frame w_y between a and b by bisection (to the last bit).
  real(dp) function wy_zero(r, a, b) result(t)
    type(free_rotor_t), intent(in) :: r
    real(dp), intent(in) :: a, b
    real(dp) :: lo, hi, flo, q(4), w(3), wb(3)
    integer :: it
    lo = a; hi = b
    call r%evaluate(lo, q, w); wb = quat_rotate_inverse(q, w); flo = wb(2)
    do it = 1, 80
      t = 0.5_dp*(lo + hi)
      call r%evaluate(t, q, w); wb = quat_rotate_inverse(q, w)
      if (wb(2)*flo > 0.0_dp) then
        lo = t
      else
        hi = t
      end if
    end do
    t = 0.5_dp*(lo + hi)
  end function wy_zero

  !> Energy, |L| and the world vector L at the given times against t = 0, to rtol.
  subroutine invariants(r, inertia, q0, w0, rtol, times, what)
    type(free_rotor_t), intent(in) :: r
    real(dp), intent(in) :: inertia(3), q0(4), w0(3), rtol, times(:)
    character(len=*), intent(in) :: what
    real(dp) :: q(4), w(3), e0, l0(3), e, l(3), wb(3), worst_e, worst_l, worst_lw
    integer :: k
    wb = quat_rotate_inverse(q0, w0)
    e0 = 0.5_dp*sum(inertia*wb**2)
    l0 = quat_rotate(q0, inertia*wb)
    worst_e = 0.0_dp; worst_l = 0.0_dp; worst_lw = 0.0_dp
    do k = 1, size(times)
      call r%evaluate(times(k), q, w)
      wb = quat_rotate_inverse(q, w)
      e = 0.5_dp*sum(inertia*wb**2)
      l = quat_rotate(q, inertia*wb)
      worst_e = max(worst_e, abs(e - e0)/e0)
      worst_l = max(worst_l, abs(norm2(l) - norm2(l0))/norm2(l0))
      worst_lw = max(worst_lw, norm2(l - l0)/norm2(l0))
    end do
    call check_close(worst_e, 0.0_dp, 0.0_dp, 'energy conserved: '//what, atol=rtol)
    call check_close(worst_l, 0.0_dp, 0.0_dp, '|L| conserved: '//what, atol=rtol)
    call check_close(worst_lw, 0.0_dp, 0.0_dp, 'world L conserved: '//what, atol=rtol)
    write (*, '(a,3es10.2)') 'invariants '//what//': rel dE, d|L|, dL_world = ', worst_e, worst_l, worst_lw
  end subroutine invariants

  subroutine composition(inertia, q0, w0, h1, h2, atol, what)
    real(dp), intent(in) :: inertia(3), q0(4), w0(3), h1, h2, atol
    character(len=*), intent(in) :: what
    type(free_rotor_t) :: a, b
    real(dp) :: qa(4), wa(3), qb(4), wb(3)
    call a%init(inertia, q0, w0)
    call a%evaluate(h1, qa, wa)
    call b%init(inertia, qa, wa)
    call b%evaluate(h2, qb, wb)
    call a%evaluate(h1 + h2, qa, wa)
    call check_close_array([qa, wa], [qb, wb], 0.0_dp, 'composition h1 then h2 = h1 + h2: '//what, atol=atol)
    write (*, '(a,es10.2)') 'composition '//what//': max diff = ', maxval(abs([qa - qb, wa - wb]))
  end subroutine composition

  !> Classical RK4 on (q, m_body): q' = q (0, w_b)/2, m' = m x w_b, w_b = m/I.
  subroutine versus_rk4(inertia, q0, w0, t_end, atol, what)
    real(dp), intent(in) :: inertia(3), q0(4), w0(3), t_end, atol
    character(len=*), intent(in) :: what
    real(dp), parameter :: dt = 1.0e-4_dp
    type(free_rotor_t) :: r
    real(dp) :: y(7), k1(7), k2(7), k3(7), k4(7), q(4), w(3), worst
    integer :: n, s
    call r%init(inertia, q0, w0)
    y(1:4) = q0
    y(5:7) = inertia*quat_rotate_inverse(q0, w0)
    n = nint(t_end/dt)
    worst = 0.0_dp
    do s = 1, n
      k1 = rhs(y, inertia); k2 = rhs(y + 0.5_dp*dt*k1, inertia)
      k3 = rhs(y + 0.5_dp*dt*k2, inertia); k4 = rhs(y + dt*k3, inertia)
      y = y + dt/6.0_dp*(k1 + 2.0_dp*k2 + 2.0_dp*k3 + k4)
      if (mod(s, 1000) == 0) then
        call r%evaluate(s*dt, q, w)
        worst = max(worst, min(maxval(abs(q - y(1:4)/norm2(y(1:4)))), maxval(abs(q + y(1:4)/norm2(y(1:4))))))
        worst = max(worst, maxval(abs(w - quat_rotate(y(1:4)/norm2(y(1:4)), y(5:7)/inertia))))
      end if
    end do
    call check_close(worst, 0.0_dp, 0.0_dp, 'matches RK4: '//what, atol=atol)
    write (*, '(a,es10.2)') 'vs RK4 '//what//': max diff = ', worst
  end subroutine versus_rk4

  function rhs(y, inertia) result(f)
    real(dp), intent(in) :: y(7), inertia(3)
    real(dp) :: f(7), wb(3)
    wb = y(5:7)/inertia
    f(1:4) = 0.5_dp*quat_mul(y(1:4), [0.0_dp, wb])
    f(5:7) = [y(6)*wb(3) - y(7)*wb(2), y(7)*wb(1) - y(5)*wb(3), y(5)*wb(2) - y(6)*wb(1)]
  end function rhs

end program test_free_rotation_exact
