!> The local loop's priority queue (event_queue) and pair store (pair_store): against a
!> brute-force reference under random inserts, moves and removals, ties broken by the global
!> ids whatever the order of insertion, and the stale-certificate check.
program test_event_queue
  use kinds, only: dp, i8
  use random_stream, only: random_stream_t
  use event_queue, only: event_queue_t
  use pair_store, only: pair_store_t
  use cell_grid, only: cell_grid_t
  use error_status, only: error_t
  use assertions
  implicit none

  call queue_against_reference()
  call queue_ties()
  call store_lists_and_versions()
  call grid_against_brute_force()
  call test_finish()

contains

  !> 2000 random operations on 300 handles: after each, the heap property holds and the top
  !> is the brute-force minimum; popping everything gives non-decreasing times.
  subroutine queue_against_reference()
    integer, parameter :: n = 300
    type(event_queue_t) :: q
    type(random_stream_t) :: rng
    real(dp) :: t_ref(n), t, last
    logical :: in_ref(n), heap_ok, top_ok
    integer :: step, h, best, k
    call q%init(8)          ! grows
    call rng%init(7)
    in_ref = .false.
    heap_ok = .true.
    top_ok = .true.
    do step = 1, 2000
      h = 1 + int(rng%uniform()*n)
      if (rng%uniform() < 0.7_dp) then
        t = rng%uniform()
        call q%set(h, t, 0_i8, 0_i8)
        t_ref(h) = t
        in_ref(h) = .true.
      else
        call q%remove(h)
        in_ref(h) = .false.
      end if
      if (.not. q%check_heap()) heap_ok = .false.
      best = 0
      do k = 1, n
        if (.not. in_ref(k)) cycle
        if (best == 0) then
          best = k
        else if (t_ref(k) < t_ref(best)) then
          best = k
        end if
      end do
      if (q%top() /= best) top_ok = .false.
    end do
    call check(heap_ok, 'queue: heap property and position index after every operation')
    call check(top_ok, 'queue: top is the brute-force earliest after every operation')
    call check(q%n == count(in_ref), 'queue: size matches the reference')
    last = -1.0_dp
    do while (.not. q%empty())
      call q%pop(h, t)
      if (t < last) top_ok = .false.
      last = t
    end do
    call check(top_ok, 'queue: pops come in non-decreasing time')
  end subroutine queue_against_reference

  !> Equal times: the order is the tie-breaks' (global ids), not the insertion order.
  subroutine queue_ties()
    type(event_queue_t) :: a, b
    integer :: h, order_a(4), order_b(4), k
    real(dp) :: t
    call a%init(4)
    call b%init(4)
    call a%set(1, 1.0_dp, 5_i8, 9_i8)
    call a%set(2, 1.0_dp, 3_i8, 7_i8)
    call a%set(3, 1.0_dp, 3_i8, 4_i8)
    call a%set(4, 0.5_dp, 99_i8, 99_i8)
    call b%set(4, 0.5_dp, 99_i8, 99_i8)
    call b%set(3, 1.0_dp, 3_i8, 4_i8)
    call b%set(1, 1.0_dp, 5_i8, 9_i8)
    call b%set(2, 1.0_dp, 3_i8, 7_i8)
    do k = 1, 4
      call a%pop(order_a(k), t)
      call b%pop(order_b(k), t)
    end do
    call check(all(order_a == [4, 3, 2, 1]), 'queue: ties taken by (tie1, tie2)')
    call check(all(order_a == order_b), 'queue: tie order independent of insertion order')
    ! moving a handle later and earlier again
    call a%set(1, 2.0_dp, 0_i8, 0_i8)
    call a%set(2, 3.0_dp, 0_i8, 0_i8)
    call a%set(2, 1.0_dp, 0_i8, 0_i8)
    h = a%top()
    call check(h == 2, 'queue: a handle moved earlier comes first')
    call check(a%time_of(1) == 2.0_dp .and. a%time_of(3) == huge(1.0_dp), 'queue: time_of present and absent')
  end subroutine queue_ties

  !> Adjacency lists stay consistent under random adds and removes; a certificate stamped
  !> with old versions is seen as stale once either body's version changes.
  subroutine store_lists_and_versions()
    integer, parameter :: n = 40
    type(pair_store_t) :: s
    type(random_stream_t) :: rng
    logical :: ref(n, n), ok_lists, ok_find
    integer(i8) :: gid(n), version(n)
    integer :: step, i, j, slot, k
    call rng%init(11)
    call s%init(n, 4)
    ref = .false.
    ok_lists = .true.
    ok_find = .true.
    gid = [(int(n - k + 1, i8), k=1, n)]     ! global ids in reverse of the local order
    do step = 1, 3000
      i = 1 + int(rng%uniform()*n)
      j = 1 + int(rng%uniform()*n)
      if (i == j) cycle
      slot = s%find(i, j)
      if ((slot > 0) .neqv. ref(min(i, j), max(i, j))) ok_find = .false.
      if (slot == 0) then
        slot = s%add(i, j, gid(i), gid(j))
        ref(min(i, j), max(i, j)) = .true.
        if (gid(s%a(slot)) >= gid(s%b(slot))) ok_find = .false.
      else
        call s%remove(slot)
        ref(min(i, j), max(i, j)) = .false.
      end if
      if (mod(step, 97) == 0) then
        if (.not. s%check()) ok_lists = .false.
      end if
    end do
    call check(ok_find, 'store: find agrees with the reference; the lower global id is a')
    call check(ok_lists .and. s%check(), 'store: every list holds its pairs exactly once')
    call check(s%n_live == count(ref), 'store: live pairs match the reference')
    ! versions
    version = 0
    do i = 1, n
      slot = s%head(i)
      if (slot > 0) exit
    end do
    s%stamp(:, slot) = [version(s%a(slot)), version(s%b(slot))]
    call check(s%current(slot, version), 'store: a certificate with the bodies'' versions is current')
    version(s%b(slot)) = version(s%b(slot)) + 1
    call check(.not. s%current(slot, version), 'store: a new trajectory version of b makes it stale')
    s%stamp(:, slot) = [version(s%a(slot)), version(s%b(slot))]
    version(s%a(slot)) = version(s%a(slot)) + 1
    call check(.not. s%current(slot, version), 'store: a new trajectory version of a makes it stale')
  end subroutine store_lists_and_versions

  !> 500 boxes of random sizes (some large), moved at random: every query returns exactly
  !> the bodies whose regions overlap, in increasing index.
  subroutine grid_against_brute_force()
    integer, parameter :: n = 500
    type(cell_grid_t) :: g
    type(random_stream_t) :: rng
    type(error_t) :: err
    real(dp) :: lower(3, n), upper(3, n)
    integer, allocatable :: found(:)
    integer :: i, j, k, step, n_found, expected
    logical :: ok, sorted
    call rng%init(3)
    call g%init(0.1_dp, n, err)
    do i = 1, n
      call random_region(rng, lower(:, i), upper(:, i))
      call g%place(i, lower(:, i), upper(:, i), err)
    end do
    ok = err%ok()
    sorted = .true.
    do step = 1, 1500
      i = 1 + int(rng%uniform()*n)
      call random_region(rng, lower(:, i), upper(:, i))
      call g%place(i, lower(:, i), upper(:, i), err)
      j = 1 + int(rng%uniform()*n)
      call g%query(j, found, n_found, n)
      expected = 0
      do k = 1, n
        if (k == j) cycle
        if (all(lower(:, k) <= upper(:, j)) .and. all(lower(:, j) <= upper(:, k))) expected = expected + 1
      end do
      if (n_found /= expected) ok = .false.
      do k = 1, n_found
        if (.not. (all(lower(:, found(k)) <= upper(:, j)) .and. all(lower(:, j) <= upper(:, found(k))))) ok = .false.
        if (k > 1) then
          if (found(k) <= found(k - 1)) sorted = .false.
        end if
      end do
    end do
    call check(ok .and. err%ok(), 'grid: queries return exactly the overlapping regions (random moves)')
    call check(sorted, 'grid: query results in increasing index')
    call g%unplace(5)
    call g%query(6, found, n_found, n)
    call check(.not. any(found(1:n_found) == 5), 'grid: an unplaced body is never returned')
  end subroutine grid_against_brute_force

  subroutine random_region(rng, lower, upper)
    type(random_stream_t), intent(inout) :: rng
    real(dp), intent(out) :: lower(3), upper(3)
    real(dp) :: c(3), half
    c = [rng%uniform(), rng%uniform(), rng%uniform()]*2.0_dp - 1.0_dp
    half = 0.02_dp + 0.1_dp*rng%uniform()
    if (rng%uniform() < 0.02_dp) half = 0.8_dp     ! a large one, kept out of the boxes
    lower = c - half
    upper = c + half
  end subroutine random_region

end program test_event_queue
