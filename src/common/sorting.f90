!> Stable index sorts (merge sort, O(n log n)) of real values and of integer key columns in
!> lexicographic order, and binary search among sorted key columns. Stable: equal values
!> keep their order, so results never depend on the sort's internals.
module sorting
  use kinds, only: dp, i8
  implicit none
  private
  public :: sort_index_real, sort_index_keys, find_key, key_less

contains

  !> order: the permutation that sorts values ascending (values(order) is sorted).
  subroutine sort_index_real(values, order)
    real(dp), intent(in) :: values(:)
    integer, allocatable, intent(out) :: order(:)
    integer, allocatable :: work(:)
    integer :: i
    order = [(i, i=1, size(values))]
    allocate (work(size(values)))
    call merge_sort(1, size(values))
  contains
    recursive subroutine merge_sort(lo, hi)
      integer, intent(in) :: lo, hi
      integer :: mid, a, b, k
      if (hi - lo < 1) return
      mid = (lo + hi)/2
      call merge_sort(lo, mid)
      call merge_sort(mid + 1, hi)
      a = lo
      b = mid + 1
      do k = lo, hi
        if (b > hi) then
          work(k) = order(a); a = a + 1
        else if (a > mid) then
          work(k) = order(b); b = b + 1
        else if (values(order(b)) < values(order(a))) then
          work(k) = order(b); b = b + 1
        else
          work(k) = order(a); a = a + 1
        end if
      end do
      order(lo:hi) = work(lo:hi)
    end subroutine merge_sort
  end subroutine sort_index_real

  !> Lexicographic a < b.
  pure logical function key_less(a, b)
    integer(i8), intent(in) :: a(:), b(:)
    integer :: k
    do k = 1, size(a)
      if (a(k) /= b(k)) then
        key_less = a(k) < b(k)
        return
      end if
    end do
    key_less = .false.
  end function key_less

  !> order: the permutation that sorts the columns of keys lexicographically.
  subroutine sort_index_keys(keys, order)
    integer(i8), intent(in) :: keys(:, :)
    integer, allocatable, intent(out) :: order(:)
    integer, allocatable :: work(:)
    integer :: i
    order = [(i, i=1, size(keys, 2))]
    allocate (work(size(keys, 2)))
    call merge_sort(1, size(keys, 2))
  contains
    recursive subroutine merge_sort(lo, hi)
      integer, intent(in) :: lo, hi
      integer :: mid, a, b, k
      if (hi - lo < 1) return
      mid = (lo + hi)/2
      call merge_sort(lo, mid)
      call merge_sort(mid + 1, hi)
      a = lo
      b = mid + 1
      do k = lo, hi
        if (b > hi) then
          work(k) = order(a); a = a + 1
        else if (a > mid) then
          work(k) = order(b); b = b + 1
        else if (key_less(keys(:, order(b)), keys(:, order(a)))) then
          work(k) = order(b); b = b + 1
        else
          work(k) = order(a); a = a + 1
        end if
      end do
      order(lo:hi) = work(lo:hi)
    end subroutine merge_sort
  end subroutine sort_index_keys

  !> Column of sorted_keys(:, 1:n) equal to key, or 0.
  pure integer function find_key(sorted_keys, n, key)
    integer(i8), intent(in) :: sorted_keys(:, :)
    integer, intent(in) :: n
    integer(i8), intent(in) :: key(:)
    integer :: lo, hi, mid
    lo = 1
    hi = n
    find_key = 0
    do while (lo <= hi)
      mid = (lo + hi)/2
      if (key_less(sorted_keys(:, mid), key)) then
        lo = mid + 1
      else if (key_less(key, sorted_keys(:, mid))) then
        hi = mid - 1
      else
        find_key = mid
        return
      end if
    end do
  end function find_key

end module sorting
