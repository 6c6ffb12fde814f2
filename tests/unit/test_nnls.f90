!> Non-negative least squares (src/math/nnls.f90), min |E x - f| over x >= 0:
!>  - optimal: on random problems (tall, wide, and rank-deficient with repeated and
!>    combined columns) the answer satisfies the KKT conditions, x >= 0, w = E^T (f - E x)
!>    <= 0 and x_i w_i = 0, to round-off relative to |E| |f|;
!>  - the true minimum: for n <= 8 the residual equals the best over every subset of
!>    columns solved unconstrained (brute force, normal equations per subset), to 1e-9;
!>  - an impact group recorded in the 8-cube pile (tests/data/nnls_pile_impact.txt, 24 x 14):
!>    x - alpha (x - z) landed a rounding above zero for the variable that set the step, the
!>    loop never dropped it, and built with -O1 and above the answer had a residual of 654
!>    against |f| = 0.68 (and the pile gained energy); now optimal;
!>  - a box landing flat on its four corners (four coplanar contacts, rank 3): E x is the
!>    exact velocity change (the box stops; no spin), and x is the minimum-norm choice of
!>    the many that give it: a quarter on each corner.
program test_nnls
  use kinds, only: dp
  use error_status, only: error_t
  use nnls, only: solve_nnls
  use random_stream, only: random_stream_t
  use assertions
  implicit none

  type(random_stream_t) :: rng
  integer :: trial

  call rng%init(20261202)
  do trial = 1, 60
    call random_problem(trial)
  end do
  call box_on_four_corners()
  call pile_impact()
  call test_finish()

contains

  subroutine random_problem(trial)
    integer, intent(in) :: trial
    real(dp), allocatable :: e(:, :), f(:), x(:), w(:)
    integer :: m, n, i, j, iterations, kind_of
    logical :: converged
    type(error_t) :: err
    real(dp) :: scale, best
    character(len=40) :: what
    kind_of = mod(trial, 3)
    select case (kind_of)
    case (0)          ! tall
      m = 6 + int(rng%uniform()*30.0_dp)
      n = 1 + int(rng%uniform()*real(m - 1, dp))
    case (1)          ! wide
      n = 4 + int(rng%uniform()*20.0_dp)
      m = 2 + int(rng%uniform()*real(n - 2, dp))
    case default      ! rank-deficient: repeated columns and sums of columns
      m = 6 + int(rng%uniform()*20.0_dp)
      n = 4 + int(rng%uniform()*10.0_dp)
    end select
    if (trial <= 24) n = min(n, 8)     ! small enough for the brute force
    allocate (e(m, n), f(m), x(n))
    do j = 1, n
      do i = 1, m
        e(i, j) = rng%symmetric(1.0_dp)
      end do
    end do
    if (kind_of == 2) then
      e(:, n) = e(:, 1)
      if (n >= 4) e(:, n - 1) = 0.5_dp*e(:, 2) + 2.0_dp*e(:, 3)
    end if
    do i = 1, m
      f(i) = rng%symmetric(1.0_dp)
    end do
    write (what, '(a,i0,a,i0,a,i0)') 'trial ', trial, ' (', m, ' x ', n
    call solve_nnls(e, f, x, iterations, err, converged)
    call check(.not. err%failed(), trim(what)//'): no error')
    call check(converged, trim(what)//'): converged')
    call check(all(x >= 0.0_dp), trim(what)//'): x >= 0')
    w = matmul(transpose(e), f - matmul(e, x))
    ! Round-off in E^T r is about eps |E| |f| times the condition of the passive columns;
    ! 1e-9 of |E| |f| leaves room for that and still fails a solver stopped one pivot early
    ! (its largest w is of order |E| |f| / n).
    scale = norm2(e)*norm2(f)
    call check(maxval(w) <= 1.0e-9_dp*scale, trim(what)//'): dual feasible, w <= 0')
    call check(maxval(abs(x*w)) <= 1.0e-9_dp*scale*max(maxval(x), 1.0_dp), trim(what)//'): complementary')
    if (n <= 8) then
      best = brute_force_residual(e, f)
      call check_close(norm2(f - matmul(e, x)), best, 1.0e-9_dp, trim(what)//'): residual = brute-force minimum', &
                       atol=1.0e-12_dp)
    end if
  end subroutine random_problem

  !> The smallest |E x - f| over every subset S of columns whose unconstrained least-squares
  !> solution on S is non-negative (the NNLS minimum is one of them).
  real(dp) function brute_force_residual(e, f) result(best)
    real(dp), intent(in) :: e(:, :), f(:)
    integer :: n, mask, j, k, info
    integer, allocatable :: cols(:)
    real(dp), allocatable :: a(:, :), g(:, :), rhs(:), z(:)
    n = size(e, 2)
    best = norm2(f)
    do mask = 1, 2**n - 1
      cols = pack([(j, j=1, n)], [(btest(mask, j - 1), j=1, n)])
      k = size(cols)
      a = e(:, cols)
      g = matmul(transpose(a), a)
      rhs = matmul(transpose(a), f)
      call cholesky_solve(g, rhs, z, info)
      if (info /= 0) cycle            ! dependent subset: a smaller one gives the same span
      if (any(z < 0.0_dp)) cycle
      best = min(best, norm2(f - matmul(a, z)))
    end do
  end function brute_force_residual

  subroutine cholesky_solve(g, b, z, info)
    real(dp), intent(inout) :: g(:, :)
    real(dp), intent(in) :: b(:)
    real(dp), allocatable, intent(out) :: z(:)
    integer, intent(out) :: info
    integer :: k, i, j
    real(dp) :: d
    k = size(b)
    info = 0
    allocate (z(k))
    do j = 1, k
      d = g(j, j) - dot_product(g(j, 1:j - 1), g(j, 1:j - 1))
      if (d <= 1.0e-10_dp*max(abs(g(j, j)), tiny(1.0_dp))) then
        info = j
        return
      end if
      g(j, j) = sqrt(d)
      do i = j + 1, k
        g(i, j) = (g(i, j) - dot_product(g(i, 1:j - 1), g(j, 1:j - 1)))/g(j, j)
      end do
    end do
    do i = 1, k
      z(i) = (b(i) - dot_product(g(i, 1:i - 1), z(1:i - 1)))/g(i, i)
    end do
    do i = k, 1, -1
      z(i) = (z(i) - dot_product(g(i + 1:k, i), z(i + 1:k)))/g(i, i)
    end do
  end subroutine cholesky_solve

  !> Unit cube (m = 1, I = 1/6) falling at 1 m/s onto four corners at (+-1/2, +-1/2, -1/2),
  !> normals +z: rows of E are (n, r x n) / sqrt(m, I) per contact; f = -v_scaled. The
  !> inelastic projection stops it: E x = -f exactly, though x is not unique.
  subroutine box_on_four_corners()
    real(dp) :: e(6, 4), f(6), x(4), corner(3, 4), n(3), r_cross_n(3), inertia
    integer :: c, iterations
    logical :: converged
    type(error_t) :: err
    inertia = 1.0_dp/6.0_dp
    corner = reshape([0.5_dp, 0.5_dp, -0.5_dp, -0.5_dp, 0.5_dp, -0.5_dp, &
                      -0.5_dp, -0.5_dp, -0.5_dp, 0.5_dp, -0.5_dp, -0.5_dp], [3, 4])
    n = [0.0_dp, 0.0_dp, 1.0_dp]
    do c = 1, 4
      r_cross_n = [corner(2, c)*n(3) - corner(3, c)*n(2), corner(3, c)*n(1) - corner(1, c)*n(3), &
                   corner(1, c)*n(2) - corner(2, c)*n(1)]
      e(1:3, c) = n
      e(4:6, c) = r_cross_n/sqrt(inertia)
    end do
    f = -[0.0_dp, 0.0_dp, -1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
    call solve_nnls(e, f, x, iterations, err, converged)
    call check(converged .and. .not. err%failed(), 'box on four corners: solved')
    call check(all(x >= 0.0_dp), 'box on four corners: x >= 0')
    call check_close_array(matmul(e, x), f, 1.0e-12_dp, 'box on four corners: stops, no spin', atol=1.0e-13_dp)
    ! Of all x >= 0 with that E x, the minimum-norm one: a quarter of the impulse on each
    ! corner (friction is bounded by each corner's own share).
    call check_close_array(x, [0.25_dp, 0.25_dp, 0.25_dp, 0.25_dp], 1.0e-12_dp, &
                           'box on four corners: load spread evenly')
  end subroutine box_on_four_corners

  subroutine pile_impact()
    integer :: unit, m, n, iterations
    real(dp), allocatable :: e(:, :), f(:), x(:), w(:)
    logical :: converged
    type(error_t) :: err
    open (newunit=unit, file=test_data_path('nnls_pile_impact.txt'), status='old', action='read')
    read (unit, *) m, n
    allocate (e(m, n), f(m), x(n))
    read (unit, *) e
    read (unit, *) f
    close (unit)
    call solve_nnls(e, f, x, iterations, err, converged)
    call check(converged .and. .not. err%failed() .and. all(x >= 0.0_dp), 'pile impact: solved')
    w = matmul(transpose(e), f - matmul(e, x))
    ! x = 0 is feasible with residual |f|: the optimum can only be below it.
    call check(norm2(f - matmul(e, x)) <= norm2(f), 'pile impact: residual below |f|')
    call check(maxval(w) <= 1.0e-9_dp*norm2(e)*norm2(f), 'pile impact: dual feasible')
    call check(maxval(abs(x*w)) <= 1.0e-9_dp*norm2(e)*norm2(f), 'pile impact: complementary')
  end subroutine pile_impact

end program test_nnls
