!> Dense linear algebra helpers on small matrices, backed by LAPACK.
module linear_algebra
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp
  use error_status, only: error_t, ERR_NUMERIC, ERR_INTERNAL
  use string_utils, only: str
  implicit none
  private
  public :: symmetric_eigen

  !> A symmetric matrix whose off-diagonal terms are all within this factor of its largest
  !> diagonal term is taken as diagonal: its eigenvectors are then the coordinate axes
  !> (so a box's principal axes are its own axes). Ignoring off-diagonal terms of relative
  !> size eps moves each eigenvalue by at most (n-1) eps relative (Weyl's inequality).
  real(dp), parameter :: diagonal_tolerance = 1.0e-12_dp
  !> Eigenvalues closer than this factor of the largest |eigenvalue| are treated as one
  !> (degenerate) cluster. Inertia tensors integrated over a mesh carry round-off of order
  !> 1e-15..1e-13 relative; truly distinct moments of real bodies differ far more than
  !> 1e-10. Inside a cluster single eigenvectors are ill-determined (they turn by
  !> round-off/gap), so the cluster's eigenspace gets a canonical basis instead.
  real(dp), parameter :: cluster_tolerance = 1.0e-10_dp

  !> Relative margin by which a later coordinate axis must beat an earlier one to be
  !> picked first when building a cluster's basis (far above round-off, far below any
  !> geometric difference).
  real(dp), parameter :: tie_tolerance = 1.0e-8_dp

  interface
    !> LAPACK: all eigenvalues (ascending) and, with jobz='V', orthonormal eigenvectors of
    !> a real symmetric matrix.
    subroutine dsyev(jobz, uplo, n, a, lda, w, work, lwork, info)
      import :: dp
      implicit none
      character(len=1), intent(in) :: jobz, uplo
      integer, intent(in) :: n, lda, lwork
      real(dp), intent(inout) :: a(lda, *)
      real(dp), intent(out) :: w(*)
      real(dp), intent(inout) :: work(*)
      integer, intent(out) :: info
    end subroutine dsyev
  end interface

contains

  !> Eigen-decomposition of the real symmetric n x n matrix a (its upper triangle is used):
  !> a = vectors diag(values) vectors^T with values ascending and vectors orthonormal.
  !>
  !> The result is made deterministic, independent of the LAPACK build's arbitrary choices:
  !>  - a (relatively) diagonal matrix gets coordinate axes, ordered by value, with ties
  !>    (cluster_tolerance) kept in index order;
  !>  - a cluster of (nearly) equal eigenvalues gets the basis of its eigenspace obtained by
  !>    pivoted Gram-Schmidt of the eigenspace projector's columns (the coordinate axes
  !>    closest to the eigenspace first), so the same eigenspace always yields the same
  !>    basis; within a cluster the vectors span the eigenspace but are not paired one to
  !>    one with the individual values, which differ only by round-off;
  !>  - a single eigenvector has its largest-magnitude component positive;
  !>  - for n = 3 the columns form a right-handed frame (det = +1): the third column is
  !>    flipped if needed.
  subroutine symmetric_eigen(a, values, vectors, err)
    real(dp), intent(in) :: a(:, :)
    real(dp), intent(out) :: values(:)
    real(dp), intent(out) :: vectors(:, :)
    type(error_t), intent(out) :: err
    real(dp), allocatable :: work(:)
    real(dp) :: query(1), scale, off
    integer :: n, i, j, info, lwork

    n = size(a, 1)
    if (size(a, 2) /= n .or. size(values) /= n .or. size(vectors, 1) /= n .or. size(vectors, 2) /= n) then
      call err%set(ERR_INTERNAL, 'symmetric_eigen: inconsistent sizes: a is '//str(size(a, 1))//' x '// &
                   str(size(a, 2))//', values '//str(size(values))//', vectors '//str(size(vectors, 1))// &
                   ' x '//str(size(vectors, 2)))
      return
    end if
    if (n == 0) return
    if (.not. all(ieee_is_finite(a))) then
      call err%set(ERR_NUMERIC, 'symmetric_eigen: the '//str(n)//' x '//str(n)// &
                   ' matrix has a NaN or infinite entry')
      return
    end if

    scale = 0.0_dp
    off = 0.0_dp
    do j = 1, n
      scale = max(scale, abs(a(j, j)))
      do i = 1, j - 1
        off = max(off, abs(a(i, j)))
      end do
    end do

    if (off <= diagonal_tolerance*scale) then
      call diagonal_eigen(a, values, vectors)
    else
      vectors = a
      call dsyev('V', 'U', n, vectors, n, values, query, -1, info)
      if (info /= 0) then
        call err%set(ERR_NUMERIC, 'symmetric_eigen: LAPACK dsyev workspace query failed, info = '//str(info))
        return
      end if
      lwork = max(1, 3*n - 1, nint(query(1)))
      allocate (work(lwork))
      call dsyev('V', 'U', n, vectors, n, values, work, lwork, info)
      if (info < 0) then
        call err%set(ERR_NUMERIC, 'symmetric_eigen: LAPACK dsyev rejected argument '//str(-info))
        return
      else if (info > 0) then
        call err%set(ERR_NUMERIC, 'symmetric_eigen: LAPACK dsyev did not converge ('//str(info)// &
                     ' off-diagonal elements of the tridiagonal form did not vanish)')
        return
      end if
      call canonical_vectors(values, vectors)
    end if

    if (n == 3) then
      if (det3(vectors) < 0.0_dp) vectors(:, 3) = -vectors(:, 3)
    end if
  end subroutine symmetric_eigen

  !> Eigen-decomposition of a matrix taken as diagonal: values are its sorted diagonal,
  !> vectors the matching coordinate axes; a cluster of equal values keeps index order.
  pure subroutine diagonal_eigen(a, values, vectors)
    real(dp), intent(in) :: a(:, :)
    real(dp), intent(out) :: values(:)
    real(dp), intent(out) :: vectors(:, :)
    integer :: order(size(values)), n, i, j, k, first, key
    real(dp) :: tol, key_value

    n = size(values)
    do i = 1, n
      values(i) = a(i, i)
      order(i) = i
    end do
    ! Stable insertion sort by value (n is tiny).
    do i = 2, n
      key = order(i)
      key_value = values(i)
      j = i - 1
      do while (j >= 1)
        if (values(j) <= key_value) exit
        values(j + 1) = values(j)
        order(j + 1) = order(j)
        j = j - 1
      end do
      values(j + 1) = key_value
      order(j + 1) = key
    end do
    ! Within clusters of (nearly) equal values, coordinate axes in index order.
    tol = cluster_tolerance*maxval(abs(values))
    first = 1
    do i = 2, n + 1
      if (i <= n) then
        if (values(i) - values(first) <= tol) cycle
      end if
      call sort_integers(order(first:i - 1))
      first = i
    end do
    vectors = 0.0_dp
    do k = 1, n
      vectors(order(k), k) = 1.0_dp
    end do
  end subroutine diagonal_eigen

  pure subroutine sort_integers(list)
    integer, intent(inout) :: list(:)
    integer :: i, j, key
    do i = 2, size(list)
      key = list(i)
      j = i - 1
      do while (j >= 1)
        if (list(j) <= key) exit
        list(j + 1) = list(j)
        j = j - 1
      end do
      list(j + 1) = key
    end do
  end subroutine sort_integers

  !> Replaces LAPACK's arbitrary choices by canonical ones: a single eigenvector gets its
  !> largest component positive; a cluster's eigenspace gets the pivoted Gram-Schmidt basis
  !> of its projector P = V V^T (columns P e_j taken largest remaining norm first; P e_j has
  !> a positive j-th component, which fixes the sign too). Norms equal to tie_tolerance
  !> count as equal and the lower index wins: symmetric bodies produce exact ties (an
  !> axisymmetric body along z: |P e1| = |P e2|), which round-off must not decide.
  pure subroutine canonical_vectors(values, vectors)
    real(dp), intent(in) :: values(:)
    real(dp), intent(inout) :: vectors(:, :)
    real(dp) :: tol, projector(size(values), size(values)), candidate(size(values)), best(size(values))
    real(dp) :: best_norm, candidate_norm
    integer :: n, first, last, i, j, k, pivot
    logical :: used(size(values))

    n = size(values)
    tol = cluster_tolerance*maxval(abs(values))
    first = 1
    do while (first <= n)
      last = first
      do while (last < n)
        if (values(last + 1) - values(first) > tol) exit
        last = last + 1
      end do
      if (last == first) then
        pivot = maxloc(abs(vectors(:, first)), dim=1)
        if (vectors(pivot, first) < 0.0_dp) vectors(:, first) = -vectors(:, first)
      else
        projector = matmul(vectors(:, first:last), transpose(vectors(:, first:last)))
        used = .false.
        do k = first, last
          best_norm = -1.0_dp
          pivot = 0
          do j = 1, n
            if (used(j)) cycle
            candidate = projector(:, j)
            do i = first, k - 1
              candidate = candidate - dot_product(vectors(:, i), candidate)*vectors(:, i)
            end do
            candidate_norm = norm2(candidate)
            if (candidate_norm > best_norm*(1.0_dp + tie_tolerance)) then
              best_norm = candidate_norm
              best = candidate
              pivot = j
            end if
          end do
          used(pivot) = .true.
          ! One re-orthogonalisation pass keeps the basis orthonormal to round-off.
          do i = first, k - 1
            best = best - dot_product(vectors(:, i), best)*vectors(:, i)
          end do
          vectors(:, k) = best/norm2(best)
        end do
      end if
      first = last + 1
    end do
  end subroutine canonical_vectors

  pure real(dp) function det3(m)
    real(dp), intent(in) :: m(3, 3)
    det3 = m(1, 1)*(m(2, 2)*m(3, 3) - m(3, 2)*m(2, 3)) - m(1, 2)*(m(2, 1)*m(3, 3) - m(3, 1)*m(2, 3)) &
           + m(1, 3)*(m(2, 1)*m(3, 2) - m(3, 1)*m(2, 2))
  end function det3

end module linear_algebra
