!> sorting: select_kth partitions around its kth element on random keys, ties, sorted,
!> reversed and constant keys, for every k, on whole arrays and on sub-ranges; both of its
!> forms give exactly the permutations of the two quickselect copies they replace (the
!> SKD-tree's and the broad-phase hierarchy's: their layouts depend on which of equal keys
!> lands where). Then the stable sorts and the key search: ordered, stable, found or 0.
!> Everything is compared exactly: keys are only compared and moved, never computed.
program test_sorting
  use kinds, only: dp, i8
  use random_stream, only: random_stream_t
  use sorting, only: select_kth, sort_index_real, sort_index_keys, find_key, key_less
  use assertions
  implicit none

  call select_on_patterns()
  call select_sub_ranges()
  call select_paired()
  call stable_sorts()
  call key_search()
  call test_finish()

contains

  !> Keys of n elements: 1 random, 2 ties (4 distinct values), 3 sorted, 4 reversed,
  !> 5 constant, 6 sorted with the middle and the ends swapped (organ pipe).
  subroutine make_keys(pattern, n, rng, key)
    integer, intent(in) :: pattern, n
    type(random_stream_t), intent(inout) :: rng
    real(dp), intent(out) :: key(n)
    integer :: i
    do i = 1, n
      select case (pattern)
      case (1)
        key(i) = rng%symmetric(1.0_dp)
      case (2)
        key(i) = real(int(rng%uniform()*4.0_dp), dp)
      case (3)
        key(i) = real(i, dp)
      case (4)
        key(i) = real(n - i, dp)
      case (5)
        key(i) = 2.5_dp
      case default
        key(i) = real(min(i, n + 1 - i), dp)
      end select
    end do
  end subroutine make_keys

  !> perm(lo:hi) is a permutation of [lo..hi] held as before, perm(kth) has the kth smallest
  !> key of the range (by a stable sort), nothing larger before it, nothing smaller after.
  logical function partitioned(perm, before, key, lo, hi, kth)
    integer, intent(in) :: perm(:), before(:), lo, hi, kth
    real(dp), intent(in) :: key(:)
    integer, allocatable :: order(:)
    logical :: seen(size(key))
    integer :: i
    partitioned = all(perm(:lo - 1) == before(:lo - 1)) .and. all(perm(hi + 1:) == before(hi + 1:))
    seen = .false.
    do i = lo, hi
      if (perm(i) < 1 .or. perm(i) > size(key)) then
        partitioned = .false.
        return
      end if
      seen(perm(i)) = .true.
    end do
    partitioned = partitioned .and. all(seen(before(lo:hi)))
    if (.not. partitioned) return
    call sort_index_real(key(before(lo:hi)), order)
    partitioned = key(perm(kth)) == key(before(lo - 1 + order(kth - lo + 1)))
    partitioned = partitioned .and. all(key(perm(lo:kth)) <= key(perm(kth))) .and. &
                  all(key(perm(kth:hi)) >= key(perm(kth)))
  end function partitioned

  !> Every k of whole arrays of 1 to 40 elements, and 1000 elements at a few k, for each
  !> pattern; the permutation must equal the former SKD-tree copy's exactly.
  subroutine select_on_patterns()
    type(random_stream_t) :: rng
    real(dp), allocatable :: key(:)
    integer, allocatable :: perm(:), before(:), reference(:)
    integer :: pattern, n, k, i, n_cases
    logical :: all_partitioned, all_same
    integer, parameter :: big_k(5) = [1, 2, 500, 999, 1000]
    call rng%init(2024)
    all_partitioned = .true.
    all_same = .true.
    n_cases = 0
    do pattern = 1, 6
      do n = 1, 41
        if (n == 41) then
          allocate (key(1000))
        else
          allocate (key(n))
        end if
        call make_keys(pattern, size(key), rng, key)
        ! a scrambled start, so that perm is not the identity
        before = [(1 + mod(7*i, size(key)), i=0, size(key) - 1)]
        if (gcd(7, size(key)) /= 1) before = [(i, i=size(key), 1, -1)]
        do k = 1, size(key)
          if (size(key) == 1000 .and. all(big_k /= k)) cycle
          perm = before
          reference = before
          call select_kth(perm, key, 1, size(key), k)
          call reference_indexed(reference, key, 1, size(key), k)
          all_partitioned = all_partitioned .and. partitioned(perm, before, key, 1, size(key), k)
          all_same = all_same .and. all(perm == reference)
          n_cases = n_cases + 1
        end do
        deallocate (key)
      end do
    end do
    call check(all_partitioned, 'select_kth partitions: random, ties, sorted, reversed, constant, organ pipe ('// &
               str_i(n_cases)//' cases)')
    call check(all_same, 'select_kth gives the former SKD-tree copy''s permutation exactly')
    ! A single element and a pair.
    allocate (key(2))
    key = [3.0_dp, 1.0_dp]
    perm = [1, 2]
    call select_kth(perm, key, 1, 1, 1)
    call check(all(perm == [1, 2]), 'a range of one element is left alone')
    call select_kth(perm, key, 1, 2, 1)
    call check(all(perm == [2, 1]), 'a pair: the smaller key first')
  end subroutine select_on_patterns

  !> A range lo:hi inside a longer array (as the SKD-tree splits its children): only that
  !> range moves, kth counted from the array's start.
  subroutine select_sub_ranges()
    type(random_stream_t) :: rng
    real(dp) :: key(60)
    integer, allocatable :: perm(:), before(:), reference(:)
    integer :: pattern, lo, hi, k, i
    logical :: all_partitioned, all_same
    call rng%init(99)
    all_partitioned = .true.
    all_same = .true.
    do pattern = 1, 6
      call make_keys(pattern, size(key), rng, key)
      before = [(size(key) + 1 - i, i=1, size(key))]
      do lo = 1, 60, 7
        do hi = lo, 60, 5
          do k = lo, hi
            perm = before
            reference = before
            call select_kth(perm, key, lo, hi, k)
            call reference_indexed(reference, key, lo, hi, k)
            all_partitioned = all_partitioned .and. partitioned(perm, before, key, lo, hi, k)
            all_same = all_same .and. all(perm == reference)
          end do
        end do
      end do
    end do
    call check(all_partitioned, 'select_kth on sub-ranges: partitions lo:hi, leaves the rest')
    call check(all_same, 'select_kth on sub-ranges: the former SKD-tree copy''s permutation')
  end subroutine select_sub_ranges

  !> The form with keys stored beside their ids (the hierarchy's): keys move with their ids,
  !> and the order is exactly the former in-place copy's.
  subroutine select_paired()
    type(random_stream_t) :: rng
    real(dp), allocatable :: key(:), key0(:), key_ref(:)
    integer, allocatable :: ids(:), ids_ref(:), identity(:)
    integer :: pattern, n, k, i
    logical :: all_partitioned, all_same, all_moved
    call rng%init(5)
    all_partitioned = .true.
    all_same = .true.
    all_moved = .true.
    do pattern = 1, 6
      do n = 1, 33
        allocate (key0(n))
        call make_keys(pattern, n, rng, key0)
        identity = [(i, i=1, n)]
        do k = 1, n
          ! ids are body ids (any values); here 1000 + i, so that they differ from positions
          ids = [(1000 + i, i=1, n)]
          key = key0
          ids_ref = ids
          key_ref = key0
          call select_kth(ids, key, k)
          call reference_paired(ids_ref, key_ref, k)
          all_same = all_same .and. all(ids == ids_ref) .and. all(key == key_ref)
          all_moved = all_moved .and. all(key == key0(ids - 1000))
          all_partitioned = all_partitioned .and. partitioned(ids - 1000, identity, key0, 1, n, k)
        end do
        deallocate (key0)
      end do
    end do
    call check(all_partitioned, 'select_kth(ids, key, k) partitions')
    call check(all_moved, 'select_kth(ids, key, k): each key stays with its id')
    call check(all_same, 'select_kth(ids, key, k) gives the former hierarchy copy''s order exactly')
  end subroutine select_paired

  !> sort_index_real and sort_index_keys: ascending (lexicographic), equal keys in their
  !> original order.
  subroutine stable_sorts()
    real(dp) :: values(8)
    integer(i8) :: keys(2, 7)
    integer, allocatable :: order(:)
    integer :: k
    logical :: ordered
    values = [3.0_dp, -1.0_dp, 2.0_dp, -1.0_dp, 3.0_dp, 0.0_dp, 2.0_dp, -1.0_dp]
    call sort_index_real(values, order)
    call check(all(order == [2, 4, 8, 6, 3, 7, 1, 5]), 'sort_index_real: ascending, ties in input order')
    call sort_index_real(values(1:0), order)
    call check(size(order) == 0, 'sort_index_real of nothing')
    keys = reshape([2_i8, 1_i8, 1_i8, 5_i8, 2_i8, 1_i8, 1_i8, 5_i8, 0_i8, 9_i8, 1_i8, 2_i8, 2_i8, 0_i8], [2, 7])
    call sort_index_keys(keys, order)
    call check(all(order == [5, 6, 2, 4, 7, 1, 3]), 'sort_index_keys: lexicographic, ties in input order')
    ordered = .true.
    do k = 2, size(order)
      ordered = ordered .and. .not. key_less(keys(:, order(k)), keys(:, order(k - 1)))
    end do
    call check(ordered, 'sort_index_keys: no column less than the one before it')
    call check(key_less([1_i8, 9_i8], [2_i8, 0_i8]) .and. key_less([1_i8, 2_i8], [1_i8, 3_i8]) .and. &
               .not. key_less([1_i8, 3_i8], [1_i8, 3_i8]) .and. .not. key_less([2_i8, 0_i8], [1_i8, 9_i8]), &
               'key_less: first differing entry decides, equal is not less')
  end subroutine stable_sorts

  !> find_key: the column of a key present in sorted columns, 0 for one absent (before,
  !> between, after), only the first n columns searched.
  subroutine key_search()
    integer(i8) :: sorted(2, 5)
    sorted = reshape([0_i8, 9_i8, 1_i8, 2_i8, 1_i8, 5_i8, 2_i8, 1_i8, 2_i8, 2_i8], [2, 5])
    call check(find_key(sorted, 5, [0_i8, 9_i8]) == 1 .and. find_key(sorted, 5, [1_i8, 5_i8]) == 3 .and. &
               find_key(sorted, 5, [2_i8, 2_i8]) == 5, 'find_key finds the first, a middle and the last column')
    call check(find_key(sorted, 5, [0_i8, 0_i8]) == 0 .and. find_key(sorted, 5, [1_i8, 3_i8]) == 0 .and. &
               find_key(sorted, 5, [3_i8, 0_i8]) == 0, 'find_key: 0 before, between and after')
    call check(find_key(sorted, 4, [2_i8, 2_i8]) == 0 .and. find_key(sorted, 0, [0_i8, 9_i8]) == 0, &
               'find_key searches only the first n columns')
  end subroutine key_search

  !> The SKD-tree's former copy (src/geometry/skd_tree.f90 before select_kth moved to
  !> sorting), verbatim: the reference for the permutations.
  subroutine reference_indexed(perm, key, lo_in, hi_in, kth)
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
  end subroutine reference_indexed

  !> The broad-phase hierarchy's former copy (src/contact/bucket_grid.f90), verbatim.
  subroutine reference_paired(ids, key, k)
    integer, intent(inout) :: ids(:)
    real(dp), intent(inout) :: key(:)
    integer, intent(in) :: k
    integer :: lo, hi, i, j, ti
    real(dp) :: pivot, tk
    lo = 1
    hi = size(key)
    do while (hi > lo)
      pivot = key((lo + hi)/2)
      i = lo
      j = hi
      do while (i <= j)
        do while (key(i) < pivot)
          i = i + 1
        end do
        do while (key(j) > pivot)
          j = j - 1
        end do
        if (i <= j) then
          tk = key(i); key(i) = key(j); key(j) = tk
          ti = ids(i); ids(i) = ids(j); ids(j) = ti
          i = i + 1
          j = j - 1
        end if
      end do
      if (k <= j) then
        hi = j
      else if (k >= i) then
        lo = i
      else
        exit
      end if
    end do
  end subroutine reference_paired

  pure integer function gcd(a, b)
    integer, intent(in) :: a, b
    integer :: x, y, t
    x = a
    y = b
    do while (y /= 0)
      t = mod(x, y)
      x = y
      y = t
    end do
    gcd = x
  end function gcd

  function str_i(i) result(text)
    integer, intent(in) :: i
    character(len=:), allocatable :: text
    character(len=16) :: buffer
    write (buffer, '(i0)') i
    text = trim(buffer)
  end function str_i

end program test_sorting
