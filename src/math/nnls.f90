!> Non-negative least squares, min |E x - f| subject to x >= 0 (Lawson & Hanson, "Solving
!> Least Squares Problems", 1974, ch. 23), with the passive columns' QR factorisation
!> updated in place instead of recomputed (Bjorck, "Numerical Methods for Least Squares
!> Problems", 1996, sec. 3.2.4 and 5.2.2).
!>
!> E_P = Q R over the passive columns P is kept as Q (m x k, orthonormal columns) and R
!> (k x k, upper triangular), with Q^T f beside them. A column entering P is orthogonalised
!> against Q by classical Gram-Schmidt with one reorthogonalisation (CGS2: orthogonal to
!> working precision); a column leaving P leaves R upper Hessenberg, and Givens rotations
!> restore it (applied to Q and Q^T f too). Each least-squares solve is then one back
!> substitution: O(m k) per Lawson-Hanson step instead of the O(m k^2) of a fresh
!> factorisation (which was most of the run time of a landing pile, docs/benchmarks.md).
!>
!> Rank deficiency, which simultaneous contact impulses produce (four coplanar contacts of
!> a box on a floor span three directions), is handled by never letting a dependent column
!> into P: a column whose component orthogonal to span(E_P) is below rank_tolerance of its
!> norm is held out until P loses a column. At a Lawson-Hanson optimum such a column's
!> gradient is zero anyway; E x (the velocity change) is unique whatever x is chosen.
!>
!> Contact matrices are sparse (a contact's column touches the 6 rows of each of its two
!> bodies, plus one row of the regularisation in the biased projection), so E is kept by
!> columns as (row, value) lists: the gradient E^T r, the residual f - E x and the first
!> Gram-Schmidt pass Q^T a cost the nonzeros instead of the whole m x n block (the dense
!> products were a sixth of a 64-cube landing at small min_separation, docs/benchmarks.md).
module nnls
  use kinds, only: dp
  use error_status, only: error_t, ERR_NUMERIC
  use string_utils, only: str
  implicit none
  private
  public :: solve_nnls, nnls_state_t

  !> A column is dependent on the passive ones when its orthogonal part is below this
  !> fraction of its norm (dgelsy's rcond was 1e-12 on the whole block; a single column's
  !> angle to the span is a sharper test, so a little looser).
  real(dp), parameter :: rank_tolerance = 1.0e-10_dp

  !> The passive set and its QR factorisation.
  type :: passive_qr_t
    integer :: k = 0
    real(dp), allocatable :: q(:, :)    !< m x kmax, columns 1..k orthonormal
    real(dp), allocatable :: r(:, :)    !< kmax x kmax, upper triangular in 1..k
    real(dp), allocatable :: qtf(:)     !< Q^T f, 1..k
    integer, allocatable :: column(:)   !< column of E at passive position p
  end type passive_qr_t

  !> E by columns: the nonzeros of column j are row(start(j):start(j+1)-1), val(same).
  type :: sparse_columns_t
    integer, allocatable :: start(:)
    integer, allocatable :: row(:)
    real(dp), allocatable :: val(:)
  end type sparse_columns_t

  !> The factorisation a solve ended with, for the next solve with the same E and another f
  !> (the rounds of a staggered solve): that one starts from this passive set and its QR,
  !> recomputing only Q^T f, instead of building the factorisation column by column again.
  !> Used only if E is the same to the bit (its nonzeros are compared).
  type :: nnls_state_t
    logical :: ready = .false.
    type(passive_qr_t) :: qr
    type(sparse_columns_t) :: cols
    logical, allocatable :: passive(:)
  end type nnls_state_t

contains

  !> x >= 0 minimising |E x - f|; iterations counts outer steps. At the iteration cap
  !> (3 n + 10: rank-deficient problems, such as many contact points on few bodies, can make
  !> the active set cycle) the loop stops with the last feasible x (x >= 0, not optimal)
  !> and converged = .false. when the argument is present, else err is set.
  !> spread (default true): move x to the minimum-norm point over the dependent columns at
  !> the end (spread_over_dependent); a caller that needs only E x may skip it.
  !> state, when present: the previous solve's factorisation, reused if E is the same, and
  !> this solve's, kept for the next (the optimum is the same from any feasible start: E x is
  !> unique, and with full-rank E so is x; the last bits may differ from a cold start).
  !> A resumed solve that has not converged after resume_iterations(n) steps is given up and
  !> the problem solved cold, as without state, so a resumed start never costs more than
  !> that bound over a cold solve and never ends unconverged where a cold one would not.
  subroutine solve_nnls(e, f, x, iterations, err, converged, spread, state)
    real(dp), intent(in) :: e(:, :), f(:)
    real(dp), intent(out) :: x(:)
    integer, intent(out) :: iterations
    type(error_t), intent(inout) :: err
    logical, intent(out), optional :: converged
    logical, intent(in), optional :: spread
    type(nnls_state_t), intent(inout), optional :: state
    type(passive_qr_t) :: qr
    type(sparse_columns_t) :: cols
    integer :: m, n, j, p, t, max_iterations, inner, kmax, blocking, resumed_steps
    logical :: passive(size(e, 2)), blocked(size(e, 2)), added, reuse
    real(dp) :: w(size(e, 2)), z(size(e, 2)), residual(size(e, 1)), tolerance, alpha, ratio, stationary

    m = size(e, 1)
    n = size(e, 2)
    x = 0.0_dp
    iterations = 0
    if (present(converged)) converged = .true.
    kmax = min(m, n)
    reuse = .false.
    resumed_steps = 0
    if (n > 0) call compress_columns(e, cols)
    if (present(state)) then
      if (state%ready .and. n > 0) then
        reuse = same_columns(state%cols, cols) .and. size(state%passive) == n
        if (reuse) reuse = size(state%qr%q, 1) == m .and. size(state%qr%q, 2) == kmax
      end if
      state%ready = .false.
    end if
    if (n == 0) return
    ! Dual-feasibility tolerance relative to the problem's scale: round-off in E^T r is about
    ! eps |E| |f|; 100 eps keeps the loop from chasing noise.
    tolerance = 100.0_dp*epsilon(1.0_dp)*max(norm2(e), tiny(1.0_dp))*max(norm2(f), tiny(1.0_dp))
    ! (the stationarity check of a resumed solve: far above round-off, far below an error)
    stationary = sqrt(epsilon(1.0_dp))*max(norm2(e), tiny(1.0_dp))*max(norm2(f), tiny(1.0_dp))
    attempt: do
      x = 0.0_dp
      passive = .false.
      blocked = .false.
      iterations = 0
      residual = f
      if (reuse) then
        ! the last passive set and its factorisation, with Q^T f for this f
        call move_alloc(state%qr%q, qr%q)
        call move_alloc(state%qr%r, qr%r)
        call move_alloc(state%qr%qtf, qr%qtf)
        call move_alloc(state%qr%column, qr%column)
        qr%k = state%qr%k
        passive = state%passive
        do p = 1, qr%k
          qr%qtf(p) = dot_product(qr%q(:, p), f)
        end do
        call drop_to_feasible(qr, x, passive)
        call residual_of(cols, f, x, residual)
        max_iterations = resume_iterations(n)
      else
        if (allocated(qr%q)) deallocate (qr%q, qr%r, qr%qtf, qr%column)
        allocate (qr%q(m, kmax), qr%r(kmax, kmax), qr%qtf(kmax), qr%column(kmax))
        qr%k = 0
        max_iterations = 3*n + 10
      end if
      call gradient(cols, residual, w)
      outer: do
        ! The most violated column that can enter (independent of the passive ones).
        added = .false.
        do
          if (.not. any(.not. passive .and. .not. blocked .and. w > tolerance)) exit
          t = maxloc(w, dim=1, mask=.not. passive .and. .not. blocked)
          if (qr%k < kmax) then
            call add_column(qr, e(:, t), f, t, added, cols)
          end if
          if (added) exit
          blocked(t) = .true.
        end do
        if (.not. added) then
          ! Optimal: x >= 0, no column outside P can lower |E x - f|. A resumed solve is
          ! also checked for stationarity on P, E_P^T r = 0, which holds to round-off when
          ! the reused factorisation still matches E_P (a gross error falls back to cold).
          if (reuse) then
            if (any(passive .and. abs(w) > stationary)) then
              resumed_steps = iterations
              reuse = .false.
              cycle attempt
            end if
          end if
          exit attempt
        end if
        iterations = iterations + 1
        if (iterations > max_iterations) then
          if (reuse) then
            ! the resumed start does not lead to the optimum soon (the reused factorisation
            ! or passive set is a poor start here): the cold solve, from nothing
            resumed_steps = iterations
            reuse = .false.
            cycle attempt
          end if
          if (present(converged)) then
            converged = .false.
          else
            call err%set(ERR_NUMERIC, 'NNLS did not converge in '//str(max_iterations)//' iterations')
          end if
          return
        end if
        passive(t) = .true.
        do inner = 1, n + 1
          call back_substitute(qr, z)
          if (all(z(1:qr%k) > 0.0_dp)) exit
          ! Step from x towards z only as far as feasibility allows, then drop the variables
          ! that reached zero.
          alpha = 1.0_dp
          blocking = 0
          do p = 1, qr%k
            j = qr%column(p)
            if (z(p) <= 0.0_dp) then
              ratio = x(j)/(x(j) - z(p))
              if (ratio < alpha .or. blocking == 0) then
                alpha = min(alpha, ratio)
                blocking = p
              end if
            end if
          end do
          do p = 1, qr%k
            j = qr%column(p)
            x(j) = x(j) + alpha*(z(p) - x(j))
          end do
          ! The variable that set the step reaches zero exactly (in floating point x - alpha (x
          ! - z) may land a rounding above it, and the loop would then never drop it).
          x(qr%column(blocking)) = 0.0_dp
          do p = qr%k, 1, -1
            j = qr%column(p)
            if (x(j) <= 0.0_dp .or. (z(p) <= 0.0_dp .and. x(j) < tiny(1.0_dp)*1.0e10_dp)) then
              x(j) = 0.0_dp
              passive(j) = .false.
              call remove_column(qr, p)
              blocked = .false.    ! the span shrank: held-out columns may be independent now
            end if
          end do
          if (qr%k == 0) exit
        end do
        x = 0.0_dp
        if (qr%k > 0) then
          call back_substitute(qr, z)
          do p = 1, qr%k
            x(qr%column(p)) = max(z(p), 0.0_dp)
          end do
        end if
        call residual_of(cols, f, x, residual)
        call gradient(cols, residual, w)
      end do outer
    end do attempt
    iterations = iterations + resumed_steps
    if (present(spread)) then
      if (spread) call spread_over_dependent(qr, e, x, w, tolerance, passive)
    else
      call spread_over_dependent(qr, e, x, w, tolerance, passive)
    end if
    if (present(state)) then
      ! kept for the next solve with this E (an unconverged one, above, keeps nothing)
      call move_alloc(qr%q, state%qr%q)
      call move_alloc(qr%r, state%qr%r)
      call move_alloc(qr%qtf, state%qr%qtf)
      call move_alloc(qr%column, state%qr%column)
      state%qr%k = qr%k
      call move_alloc(cols%start, state%cols%start)
      call move_alloc(cols%row, state%cols%row)
      call move_alloc(cols%val, state%cols%val)
      state%passive = passive
      state%ready = .true.
    end if
  end subroutine solve_nnls

  !> Columns whose least-squares values on the passive set are not positive leave it, until
  !> none is: x >= 0 then, positive exactly on the passive set and optimal over it, where a
  !> Lawson-Hanson step may begin.
  subroutine drop_to_feasible(qr, x, passive)
    type(passive_qr_t), intent(inout) :: qr
    real(dp), intent(out) :: x(:)
    logical, intent(inout) :: passive(:)
    real(dp) :: z(size(x))
    integer :: p
    do while (qr%k > 0)
      call back_substitute(qr, z)
      if (all(z(1:qr%k) > 0.0_dp)) exit
      ! (not z > 0 rather than z <= 0: a NaN leaves too, so every pass removes a column)
      do p = qr%k, 1, -1
        if (.not. (z(p) > 0.0_dp)) then
          passive(qr%column(p)) = .false.
          call remove_column(qr, p)
        end if
      end do
    end do
    x = 0.0_dp
    if (qr%k > 0) then
      call back_substitute(qr, z)
      do p = 1, qr%k
        x(qr%column(p)) = z(p)
      end do
    end if
  end subroutine drop_to_feasible

  !> The step cap of a resumed solve. Resumed from the last round's passive set, a solve
  !> usually ends in a few steps (at most 24, mostly under 4, in the 64-cube pours); one that
  !> needs more than this is solved cold instead, so a poor start costs at most this many
  !> steps more than the cold solve would.
  pure integer function resume_iterations(n)
    integer, intent(in) :: n
    resume_iterations = n/4 + 10
  end function resume_iterations

  !> The same nonzeros, bit for bit.
  pure logical function same_columns(a, b)
    type(sparse_columns_t), intent(in) :: a, b
    same_columns = .false.
    if (.not. (allocated(a%start) .and. allocated(b%start))) return
    if (size(a%start) /= size(b%start) .or. size(a%row) /= size(b%row)) return
    same_columns = all(a%start == b%start) .and. all(a%row == b%row) .and. all(a%val == b%val)
  end function same_columns

  !> E x is unique, x is not when columns outside P have zero gradient and lie in the span
  !> of P and each other (the four corners of a box face: the answer above loads two
  !> diagonal corners and leaves the others at zero, which friction, bounded by each
  !> contact's own normal impulse, would feel). Moves x within {z >= 0, E z = E x} towards
  !> the minimum-norm point over P and those columns, as the rank-revealing least-squares
  !> solve did: a box on four corners then carries a quarter on each.
  !> The zero-gradient columns join the factorisation one by one (at x = 0) while they are
  !> independent; each dependent one, e_d = E_B c_d over the basis B so grown, gives the null
  !> direction (-c_d on B, 1 on d).
  subroutine spread_over_dependent(qr_in, e, x, w, tolerance, passive)
    type(passive_qr_t), intent(in) :: qr_in
    real(dp), intent(in) :: e(:, :), w(:), tolerance
    real(dp), intent(inout) :: x(:)
    logical, intent(in) :: passive(:)
    type(passive_qr_t) :: qr
    integer, allocatable :: dependent(:)
    real(dp), allocatable :: c(:, :), gram(:, :), y(:), step(:), coeff(:)
    real(dp) :: zero_rhs(size(e, 1)), alpha
    integer :: j, n_dep, d, k, i, info
    logical :: added
    if (qr_in%k == 0) return
    qr = qr_in
    zero_rhs = 0.0_dp
    allocate (dependent(size(x)))
    n_dep = 0
    do j = 1, size(x)
      if (passive(j) .or. abs(w(j)) > tolerance) cycle
      if (norm2(e(:, j)) <= 0.0_dp) cycle
      added = .false.
      if (qr%k < size(qr%q, 2)) call add_column(qr, e(:, j), zero_rhs, j, added)
      if (added) cycle
      n_dep = n_dep + 1
      dependent(n_dep) = j
    end do
    if (n_dep == 0) return
    ! c(:, d) = R^-1 Q^T e_d: the basis combination equal to dependent column d (to the rank
    ! tolerance; the check below keeps only exact ones).
    k = qr%k
    allocate (c(k, n_dep))
    do d = 1, n_dep
      coeff = matmul(e(:, dependent(d)), qr%q(:, 1:k))
      if (norm2(e(:, dependent(d)) - matmul(qr%q(:, 1:k), coeff)) > 10.0_dp*rank_tolerance*norm2(e(:, dependent(d)))) &
        return
      do i = k, 1, -1
        c(i, d) = (coeff(i) - dot_product(qr%r(i, i + 1:k), c(i + 1:k, d)))/qr%r(i, i)
      end do
    end do
    ! Minimum norm along the null directions N: y = (N^T N)^-1 N^T x, z = x - N y, with
    ! N^T N = C^T C + I (symmetric positive definite, at least the identity).
    gram = matmul(transpose(c), c)
    allocate (y(n_dep))
    do d = 1, n_dep
      gram(d, d) = gram(d, d) + 1.0_dp
      y(d) = x(dependent(d)) - dot_product(c(:, d), x(qr%column(1:k)))
    end do
    call cholesky_solve_small(gram, y, info)
    if (info /= 0) return
    ! step = z - x = -N y
    allocate (step(size(x)))
    step = 0.0_dp
    step(qr%column(1:k)) = matmul(c, y)
    step(dependent(1:n_dep)) = -y
    ! As far towards z as x >= 0 allows (E x does not change along N).
    alpha = 1.0_dp
    do j = 1, size(x)
      if (step(j) < 0.0_dp) alpha = min(alpha, x(j)/(-step(j)))
    end do
    x = max(x + alpha*step, 0.0_dp)
  end subroutine spread_over_dependent

  !> Solves G y = b in place (G small, symmetric positive definite); info /= 0 if not.
  pure subroutine cholesky_solve_small(g, y, info)
    real(dp), intent(inout) :: g(:, :), y(:)
    integer, intent(out) :: info
    integer :: i, j, n
    real(dp) :: d
    n = size(y)
    info = 0
    do j = 1, n
      d = g(j, j) - dot_product(g(j, 1:j - 1), g(j, 1:j - 1))
      if (d <= 0.0_dp) then
        info = j
        return
      end if
      g(j, j) = sqrt(d)
      do i = j + 1, n
        g(i, j) = (g(i, j) - dot_product(g(i, 1:j - 1), g(j, 1:j - 1)))/g(j, j)
      end do
    end do
    do i = 1, n
      y(i) = (y(i) - dot_product(g(i, 1:i - 1), y(1:i - 1)))/g(i, i)
    end do
    do i = n, 1, -1
      y(i) = (y(i) - dot_product(g(i + 1:n, i), y(i + 1:n)))/g(i, i)
    end do
  end subroutine cholesky_solve_small

  !> Appends column t (values a) to the factorisation unless it is dependent on the passive
  !> columns (added = .false.).
  !> cols (E by columns, a = column t of it): the first pass Q^T a over a's nonzeros only.
  subroutine add_column(qr, a, f, t, added, cols)
    type(passive_qr_t), intent(inout) :: qr
    real(dp), intent(in) :: a(:), f(:)
    integer, intent(in) :: t
    logical, intent(out) :: added
    type(sparse_columns_t), intent(in), optional :: cols
    real(dp) :: v(size(a)), c(qr%k), rcol(qr%k + 1), norm_a, rho
    integer :: k, pass, p
    k = qr%k
    added = .false.
    norm_a = norm2(a)
    if (norm_a <= 0.0_dp) return
    v = a
    rcol = 0.0_dp
    do pass = 1, 2
      if (k > 0) then
        if (pass == 1 .and. present(cols)) then
          c = 0.0_dp
          do p = cols%start(t), cols%start(t + 1) - 1
            c = c + cols%val(p)*qr%q(cols%row(p), 1:k)
          end do
        else
          c = matmul(v, qr%q(:, 1:k))
        end if
        v = v - matmul(qr%q(:, 1:k), c)
        rcol(1:k) = rcol(1:k) + c
      end if
    end do
    rho = norm2(v)
    if (rho <= rank_tolerance*norm_a) return
    qr%q(:, k + 1) = v/rho
    qr%r(1:k, k + 1) = rcol(1:k)
    qr%r(k + 1, k + 1) = rho
    qr%r(k + 1, 1:k) = 0.0_dp
    qr%qtf(k + 1) = dot_product(qr%q(:, k + 1), f)
    qr%column(k + 1) = t
    qr%k = k + 1
    added = .true.
  end subroutine add_column

  !> Removes passive position p: R loses a column, Givens rotations on rows p..k restore the
  !> triangle, and the same rotations keep Q and Q^T f consistent.
  subroutine remove_column(qr, p)
    type(passive_qr_t), intent(inout) :: qr
    integer, intent(in) :: p
    integer :: j, k, m
    real(dp) :: a, b, c, s, rr, row_j(qr%k), row_j1(qr%k), qj(size(qr%q, 1))
    k = qr%k
    m = size(qr%q, 1)
    do j = p, k - 1
      qr%r(1:k, j) = qr%r(1:k, j + 1)
      qr%column(j) = qr%column(j + 1)
    end do
    ! Columns p..k-1 now have one entry below the diagonal, r(j+1, j).
    do j = p, k - 1
      a = qr%r(j, j)
      b = qr%r(j + 1, j)
      rr = hypot(a, b)
      if (rr == 0.0_dp) cycle
      c = a/rr
      s = b/rr
      row_j(j:k - 1) = qr%r(j, j:k - 1)
      row_j1(j:k - 1) = qr%r(j + 1, j:k - 1)
      qr%r(j, j:k - 1) = c*row_j(j:k - 1) + s*row_j1(j:k - 1)
      qr%r(j + 1, j:k - 1) = -s*row_j(j:k - 1) + c*row_j1(j:k - 1)
      qr%r(j + 1, j) = 0.0_dp
      qj = qr%q(:, j)
      qr%q(:, j) = c*qj + s*qr%q(:, j + 1)
      qr%q(:, j + 1) = -s*qj + c*qr%q(:, j + 1)
      a = qr%qtf(j)
      qr%qtf(j) = c*a + s*qr%qtf(j + 1)
      qr%qtf(j + 1) = -s*a + c*qr%qtf(j + 1)
    end do
    qr%k = k - 1
  end subroutine remove_column

  !> The nonzeros of e, column by column (rows in increasing order).
  pure subroutine compress_columns(e, cols)
    real(dp), intent(in) :: e(:, :)
    type(sparse_columns_t), intent(out) :: cols
    integer :: i, j, nnz
    allocate (cols%start(size(e, 2) + 1))
    nnz = count(e /= 0.0_dp)
    allocate (cols%row(nnz), cols%val(nnz))
    nnz = 0
    do j = 1, size(e, 2)
      cols%start(j) = nnz + 1
      do i = 1, size(e, 1)
        if (e(i, j) /= 0.0_dp) then
          nnz = nnz + 1
          cols%row(nnz) = i
          cols%val(nnz) = e(i, j)
        end if
      end do
    end do
    cols%start(size(e, 2) + 1) = nnz + 1
  end subroutine compress_columns

  !> w = E^T r.
  pure subroutine gradient(cols, r, w)
    type(sparse_columns_t), intent(in) :: cols
    real(dp), intent(in) :: r(:)
    real(dp), intent(out) :: w(:)
    integer :: j, p
    do j = 1, size(w)
      w(j) = 0.0_dp
      do p = cols%start(j), cols%start(j + 1) - 1
        w(j) = w(j) + cols%val(p)*r(cols%row(p))
      end do
    end do
  end subroutine gradient

  !> r = f - E x.
  pure subroutine residual_of(cols, f, x, r)
    type(sparse_columns_t), intent(in) :: cols
    real(dp), intent(in) :: f(:), x(:)
    real(dp), intent(out) :: r(:)
    integer :: j, p
    r = f
    do j = 1, size(x)
      if (x(j) == 0.0_dp) cycle
      do p = cols%start(j), cols%start(j + 1) - 1
        r(cols%row(p)) = r(cols%row(p)) - cols%val(p)*x(j)
      end do
    end do
  end subroutine residual_of

  !> z(1:k) = R^-1 Q^T f: the least-squares solution on the passive columns.
  pure subroutine back_substitute(qr, z)
    type(passive_qr_t), intent(in) :: qr
    real(dp), intent(out) :: z(:)
    integer :: i, k
    k = qr%k
    do i = k, 1, -1
      z(i) = (qr%qtf(i) - dot_product(qr%r(i, i + 1:k), z(i + 1:k)))/qr%r(i, i)
    end do
  end subroutine back_substitute

end module nnls
