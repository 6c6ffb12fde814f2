!> Non-negative least squares, min |E x - f| subject to x >= 0 (Lawson & Hanson, "Solving
!> Least Squares Problems", 1974, ch. 23). Finite, exact up to round-off, and well defined
!> when E is rank deficient (the inner solves use a rank-revealing QR, LAPACK dgelsy), which
!> is what simultaneous contact impulses need: four coplanar contacts of a box on a floor
!> give a singular contact matrix, but E x (the velocity change) is still unique.
module nnls
  use kinds, only: dp
  use error_status, only: error_t, ERR_NUMERIC
  use string_utils, only: str
  implicit none
  private
  public :: solve_nnls

  interface
    subroutine dgelsy(m, n, nrhs, a, lda, b, ldb, jpvt, rcond, rank, work, lwork, info)
      import :: dp
      integer, intent(in) :: m, n, nrhs, lda, ldb, lwork
      real(dp), intent(inout) :: a(lda, *), b(ldb, *)
      integer, intent(inout) :: jpvt(*)
      real(dp), intent(in) :: rcond
      integer, intent(out) :: rank, info
      real(dp), intent(inout) :: work(*)
    end subroutine dgelsy
  end interface

contains

  !> x >= 0 minimising |E x - f|; iterations counts outer steps. At the iteration cap
  !> (3 n + 10: rank-deficient problems, such as many contact points on few bodies, can make
  !> the active set cycle) the loop stops with the last feasible x (x >= 0, not optimal)
  !> and converged = .false. when the argument is present, else err is set.
  subroutine solve_nnls(e, f, x, iterations, err, converged)
    real(dp), intent(in) :: e(:, :), f(:)
    real(dp), intent(out) :: x(:)
    integer, intent(out) :: iterations
    type(error_t), intent(inout) :: err
    logical, intent(out), optional :: converged
    integer :: m, n, n_passive, j, t, max_iterations, inner
    logical :: passive(size(e, 2))
    real(dp) :: w(size(e, 2)), z(size(e, 2)), residual(size(e, 1)), tolerance, alpha, ratio
    integer :: index_of(size(e, 2))

    m = size(e, 1)
    n = size(e, 2)
    x = 0.0_dp
    passive = .false.
    iterations = 0
    if (present(converged)) converged = .true.
    max_iterations = 3*n + 10
    ! Dual-feasibility tolerance relative to the problem's scale: round-off in E^T r is about
    ! eps |E| |f|; 100 eps keeps the loop from chasing noise.
    tolerance = 100.0_dp*epsilon(1.0_dp)*max(norm2(e), tiny(1.0_dp))*max(norm2(f), tiny(1.0_dp))
    residual = f
    w = matmul(transpose(e), residual)
    do
      if (all(passive) .or. .not. any(.not. passive .and. w > tolerance)) exit
      iterations = iterations + 1
      if (iterations > max_iterations) then
        if (present(converged)) then
          converged = .false.
        else
          call err%set(ERR_NUMERIC, 'NNLS did not converge in '//str(max_iterations)//' iterations')
        end if
        return
      end if
      t = maxloc(w, dim=1, mask=.not. passive)
      passive(t) = .true.
      do inner = 1, n + 1
        n_passive = count(passive)
        index_of(1:n_passive) = pack([(j, j=1, n)], passive)
        call least_squares(e(:, index_of(1:n_passive)), f, z(1:n_passive), err)
        if (err%failed()) return
        if (all(z(1:n_passive) > 0.0_dp)) exit
        ! Step from x towards z only as far as feasibility allows, then drop the variables
        ! that reached zero.
        alpha = 1.0_dp
        do j = 1, n_passive
          if (z(j) <= 0.0_dp) then
            ratio = x(index_of(j))/(x(index_of(j)) - z(j))
            alpha = min(alpha, ratio)
          end if
        end do
        do j = 1, n_passive
          x(index_of(j)) = x(index_of(j)) + alpha*(z(j) - x(index_of(j)))
          if (x(index_of(j)) <= 0.0_dp .or. (z(j) <= 0.0_dp .and. x(index_of(j)) < tiny(1.0_dp)*1.0e10_dp)) then
            x(index_of(j)) = 0.0_dp
            passive(index_of(j)) = .false.
          end if
        end do
        if (.not. any(passive)) exit
      end do
      x = 0.0_dp
      n_passive = count(passive)
      if (n_passive > 0) then
        index_of(1:n_passive) = pack([(j, j=1, n)], passive)
        do j = 1, n_passive
          x(index_of(j)) = max(z(j), 0.0_dp)
        end do
      end if
      residual = f - matmul(e, x)
      w = matmul(transpose(e), residual)
    end do
  end subroutine solve_nnls

  !> Minimum-norm least-squares solution of A z = f (A: m x k), rank-revealing.
  subroutine least_squares(a, f, z, err)
    real(dp), intent(in) :: a(:, :), f(:)
    real(dp), intent(out) :: z(:)
    type(error_t), intent(inout) :: err
    real(dp), allocatable :: a_copy(:, :), rhs(:, :), work(:)
    integer, allocatable :: pivots(:)
    integer :: m, k, rank, info, lwork
    real(dp) :: query(1)
    m = size(a, 1)
    k = size(a, 2)
    a_copy = a
    allocate (rhs(max(m, k), 1), pivots(k))
    rhs = 0.0_dp
    rhs(1:m, 1) = f
    pivots = 0
    call dgelsy(m, k, 1, a_copy, m, rhs, max(m, k), pivots, 1.0e-12_dp, rank, query, -1, info)
    lwork = int(query(1))
    allocate (work(lwork))
    call dgelsy(m, k, 1, a_copy, m, rhs, max(m, k), pivots, 1.0e-12_dp, rank, work, lwork, info)
    if (info /= 0) then
      call err%set(ERR_NUMERIC, 'LAPACK dgelsy failed with info = '//str(info))
      return
    end if
    z = rhs(1:k, 1)
  end subroutine least_squares

end module nnls
