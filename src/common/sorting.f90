!> Stable index sorts (merge sort, O(n log n)) of real values and of integer key columns in
!> lexicographic order, and binary search among sorted key columns. Stable: equal values
!> keep their order, so results never depend on the sort's internals.
!> And select_kth, the median split of the SKD-trees and of the broad phase's hierarchy
!> (quickselect, O(n) on average). It is not stable: which of equal keys lands where
!> depends on its internals, and the trees' layouts depend on that, so its algorithm (Hoare
!> partition, middle pivot) is fixed: changing it changes the trees bit for bit.
module sorting
  use kinds, only: dp, i8
  implicit none
  private
  public :: sort_index_real, sort_index_keys, find_key, key_less, select_kth, keeps_first

  !> select_kth(perm, key, lo, hi, kth): key indexed by perm's entries (key(perm(i)));
  !> select_kth(ids, key, k): key(i) belongs to ids(i) and moves with it. Both give the
  !> same order for the same keys: the second is the first applied to positions.
  interface select_kth
    module procedure select_kth_indexed, select_kth_paired
  end interface select_kth

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

  !> Reorders perm(lo_in:hi_in) so that perm(kth) has the kth smallest key among them (its
  !> rank counted from lo_in), no larger key before it and no smaller one after it:
  !> key(perm(lo_in:kth-1)) <= key(perm(kth)) <= key(perm(kth+1:hi_in)). Entries outside
  !> lo_in:hi_in are not touched. Hoare's quickselect with the middle element as pivot.
  pure subroutine select_kth_indexed(perm, key, lo_in, hi_in, kth)
    integer, intent(inout) :: perm(:)
    real(dp), intent(in) :: key(:)
    integer, intent(in) :: lo_in, hi_in, kth
    integer :: lo, hi, i, j, tmp
    real(dp) :: pivot
    lo = lo_in
    hi = hi_in
    do while (lo < hi)
      pivot = key(perm((lo + hi)/2))
      i = lo
      j = hi
      do while (i <= j)
        do while (key(perm(i)) < pivot)
          i = i + 1
        end do
        do while (key(perm(j)) > pivot)
          j = j - 1
        end do
        if (i <= j) then
          tmp = perm(i); perm(i) = perm(j); perm(j) = tmp
          i = i + 1
          j = j - 1
        end if
      end do
      if (kth <= j) then
        hi = j
      else if (kth >= i) then
        lo = i
      else
        exit
      end if
    end do
  end subroutine select_kth_indexed

  !> Partial sort: afterwards key(1:k) <= key(k+1:), ids moved with their keys (the same
  !> order as select_kth_indexed on positions 1..size(key)).
  pure subroutine select_kth_paired(ids, key, k)
    integer, intent(inout) :: ids(:)
    real(dp), intent(inout) :: key(:)
    integer, intent(in) :: k
    integer, allocatable :: order(:)
    integer :: i
    order = [(i, i=1, size(key))]
    call select_kth_indexed(order, key, 1, size(key), k)
    ids = ids(order)
    key = key(order)
  end subroutine select_kth_paired

  !> Whether a renumbering keeps rows 1..n where they are (new_index(k) = k for k <= n):
  !> rows were only appended, which the renumbered structures (cell_grid, pair_store) take
  !> without rebuilding anything.
  pure logical function keeps_first(new_index, n) result(keeps)
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n
    integer :: k
    keeps = size(new_index) >= n
    if (.not. keeps) return
    do k = 1, n
      if (new_index(k) /= k) then
        keeps = .false.
        return
      end if
    end do
  end function keeps_first

end module sorting
