!> The local loop's priority queue (event_queue) and pair store (pair_store): against a
!> brute-force reference under random inserts, moves and removals, ties broken by the global
!> ids whatever the order of insertion, and the stale-certificate check. And the three
!> renumbered as a migration renumbers a rank's bodies (remap_bodies, remap_handles: some
!> leave, the others keep their order among new arrivals): everything kept is kept as it was.
!> And the undo journals of the queue and the store (a cross-rank window's save): random
!> changes, with growth, rolled back give the state of the journal's start bit for bit.
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
  call renumbering()
  call queue_journal()
  call store_journal()
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

  !> The queue's undo journal: 120 handles queued, the journal started, 400 random sets,
  !> removals and pops (handles up to 3x the capacity: the queue grows) rolled back; twice
  !> (the journal goes on from the state rolled back to). Each time the heap holds and the
  !> same handles are queued with the start's times and tie-breaks, bit for bit (the layout
  !> is rebuilt, not restored: the order is total, so the pops follow); then the queue pops
  !> in the copy's order. Negative control: without the roll back, the entries differ.
  subroutine queue_journal()
    type(event_queue_t) :: q, start
    type(random_stream_t) :: rng
    integer :: h, round
    real(dp) :: t
    logical :: same
    call rng%init(5)
    call q%init(64)
    do h = 1, 120
      call q%set(h, rng%uniform(), int(mod(h, 7), i8), int(h, i8))
    end do
    start = q
    call q%start_journal()
    do round = 1, 2
      call scramble(q, rng)
      call check(.not. same_queue(q, start), 'queue journal: the changes changed the queue (control)')
      call q%roll_back()
      call check(q%check_heap() .and. same_queue(q, start), 'queue journal: rolled back to the start, round '// &
                 achar(48 + round))
    end do
    call q%stop_journal()
    same = .true.
    do while (.not. start%empty())
      call start%pop(h, t)
      call q%pop(round, t)
      if (h /= round) same = .false.
    end do
    call check(same .and. q%empty(), 'queue journal: the rolled-back queue pops in the start''s order')
  end subroutine queue_journal

  !> 400 random sets, removals and pops of handles up to 360.
  subroutine scramble(x, rng)
    type(event_queue_t), intent(inout) :: x
    type(random_stream_t), intent(inout) :: rng
    real(dp) :: t
    integer :: step, k
    real(dp) :: u
    do step = 1, 400
      k = 1 + int(rng%uniform()*360)
      u = rng%uniform()
      if (u < 0.6_dp) then
        call x%set(k, rng%uniform(), int(mod(k, 5), i8), int(k, i8))
      else if (u < 0.85_dp) then
        call x%remove(k)
      else
        call x%pop(k, t)
      end if
    end do
  end subroutine scramble

  !> The same handles queued, with the same times and tie-breaks (not the same layout).
  logical function same_queue(x, y)
    type(event_queue_t), intent(in) :: x, y
    integer :: h
    same_queue = x%n == y%n
    if (.not. same_queue) return
    do h = 1, max(size(x%pos), size(y%pos))
      if ((pos_of(x, h) > 0) .neqv. (pos_of(y, h) > 0)) same_queue = .false.
      if (pos_of(x, h) > 0 .and. pos_of(y, h) > 0) then
        if (.not. (x%time(h) == y%time(h) .and. all(x%tie(:, h) == y%tie(:, h)))) same_queue = .false.
      end if
    end do
  end function same_queue

  integer function pos_of(x, h)
    type(event_queue_t), intent(in) :: x
    integer, intent(in) :: h
    pos_of = 0
    if (h <= size(x%pos)) pos_of = x%pos(h)
  end function pos_of

  !> The store's undo journal: 40 bodies, 300 random pairs, the journal started, then 600
  !> random adds, removals and certificate writes (touch first; slots beyond the capacity:
  !> the store grows) rolled back, twice. Each time every live slot's fields, the lists, the
  !> free list up to its count and the counts are the start's, bit for bit. Negative
  !> control: a write without touch is not undone.
  subroutine store_journal()
    integer, parameter :: n = 40
    type(pair_store_t) :: s, start
    type(random_stream_t) :: rng
    integer(i8) :: gid(n)
    integer :: k, round, slot
    call rng%init(13)
    gid = [(int(3*k + 1, i8), k=1, n)]
    call s%init(n, 64)
    call churn(s, rng, gid, 300, .true.)
    start = s
    call s%start_journal()
    do round = 1, 2
      call churn(s, rng, gid, 600, .true.)
      call check(.not. same_store(s, start), 'store journal: the changes changed the store (control)')
      call s%roll_back()
      call check(s%check() .and. same_store(s, start), 'store journal: rolled back to the start, round '// &
                 achar(48 + round))
    end do
    ! a certificate written without touch stays written (what touch is for)
    slot = 0
    do k = 1, s%n_slots
      if (s%a(k) > 0) then
        slot = k
        exit
      end if
    end do
    s%gap(slot) = -1.0_dp
    call s%roll_back()
    call check(.not. same_store(s, start), 'store journal: a write without touch is not undone (control)')
    call s%stop_journal()
  end subroutine store_journal

  !> steps random adds and removals among n bodies of global ids gid, the certificate
  !> fields of the pairs added or kept written (touch: touched first).
  subroutine churn(x, rng, gid, steps, touch)
    type(pair_store_t), intent(inout) :: x
    type(random_stream_t), intent(inout) :: rng
    integer(i8), intent(in) :: gid(:)
    integer, intent(in) :: steps
    logical, intent(in) :: touch
    integer :: step, i, j, q
    do step = 1, steps
      i = 1 + int(rng%uniform()*size(gid))
      j = 1 + int(rng%uniform()*size(gid))
      if (i == j) cycle
      q = x%find(i, j)
      if (q == 0) then
        q = x%add(i, j, gid(i), gid(j))
      else if (rng%uniform() < 0.5_dp) then
        call x%remove(q)
        cycle
      end if
      if (touch) call x%touch(q)
      x%t_due(q) = rng%uniform()
      x%gap(q) = rng%uniform()
      x%normal(:, q) = [rng%uniform(), rng%uniform(), rng%uniform()]
      x%stamp(:, q) = x%stamp(:, q) + 1
      x%action(q) = 1 + mod(step, 3)
      x%far(q) = mod(step, 2) == 0
    end do
  end subroutine churn

  logical function same_store(x, y)
    type(pair_store_t), intent(in) :: x, y
    integer :: k, m
    same_store = x%n_slots == y%n_slots .and. x%n_live == y%n_live .and. x%n_free == y%n_free
    if (.not. same_store) return
    m = x%n_slots
    same_store = all(x%a(1:m) == y%a(1:m)) .and. all(x%b(1:m) == y%b(1:m)) .and. &
                 all(x%head == y%head(1:size(x%head))) .and. all(x%degree == y%degree(1:size(x%degree))) .and. &
                 all(x%free_slots(1:x%n_free) == y%free_slots(1:y%n_free))
    do k = 1, m
      if (x%a(k) == 0) cycle
      if (any(x%next(:, k) /= y%next(:, k)) .or. any(x%stamp(:, k) /= y%stamp(:, k)) .or. &
          x%t_due(k) /= y%t_due(k) .or. x%gap(k) /= y%gap(k) .or. any(x%normal(:, k) /= y%normal(:, k)) .or. &
          x%action(k) /= y%action(k) .or. (x%far(k) .neqv. y%far(k)) .or. x%t_query(k) /= y%t_query(k) .or. &
          x%certified_until(k) /= y%certified_until(k) .or. (x%in_pass(k) .neqv. y%in_pass(k))) same_store = .false.
    end do
  end function same_store

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

  !> 60 bodies, of which about a quarter leave; the others become rows of 120 in their old
  !> order, with arrivals between them (what migrate_bodies' new_index looks like).
  subroutine renumbering()
    integer, parameter :: n = 60, n_new = 2 * n
    type(event_queue_t) :: q, ref
    type(pair_store_t) :: s
    type(cell_grid_t) :: g
    type(random_stream_t) :: rng
    type(error_t) :: err
    integer :: new_index(n), old_of(n_new), i, j, k, slot, h, h_ref, n_dropped, n_found, expected
    integer, allocatable :: dropped(:), found(:), old_list(:, :), old_len(:)
    integer(i8) :: gid(n)
    real(dp) :: t, t_ref, lower(3, n), upper(3, n), gap_of(4 * n * n)
    logical :: ok, order_ok, kept_ok, drop_ok
    integer :: old_a(4 * n * n), old_b(4 * n * n), n_slots_before
    call rng%init(23)
    gid = [(int(3 * k + 1, i8), k=1, n)]
    ! the renumbering: a body leaves with probability 1/4; rows after keep the old order
    new_index = 0
    old_of = 0
    j = 0
    do i = 1, n
      if (rng%uniform() < 0.25_dp) cycle
      j = j + 1 + merge(1, 0, rng%uniform() < 0.3_dp)     ! (an arrival takes the row between)
      new_index(i) = j
      old_of(j) = i
    end do
    ! queue: handles are bodies (box crossings), ties by gid
    call q%init(8)
    call ref%init(8)
    do i = 1, n
      t = real(int(rng%uniform() * 5.0_dp), dp)    ! many equal times: the ties decide
      call q%set(i, t, gid(i), 0_i8)
      if (new_index(i) > 0) call ref%set(new_index(i), t, gid(i), 0_i8)
    end do
    call q%remap_handles(new_index, n_new)
    ok = q%check_heap() .and. q%n == ref%n
    do while (.not. ref%empty())
      call q%pop(h, t)
      call ref%pop(h_ref, t_ref)
      if (h /= h_ref .or. t /= t_ref) ok = .false.
    end do
    call check(ok .and. q%empty(), 'queue renumbered: heap holds, entries renamed, the same order as queued afresh')
    call q%set(n_new, 0.0_dp, 0_i8, 0_i8)
    call check(q%top() == n_new, 'queue renumbered: room for the new handles')
    ! pair store: random pairs with distinct certificates
    call s%init(n, 8)
    call add_random_pairs(s, rng, gid, 400)
    n_slots_before = s%n_slots
    old_a(1:n_slots_before) = s%a(1:n_slots_before)
    old_b(1:n_slots_before) = s%b(1:n_slots_before)
    gap_of(1:n_slots_before) = s%gap(1:n_slots_before)
    allocate (old_list(n, n_slots_before), old_len(n))
    do i = 1, n
      old_len(i) = 0
      slot = s%head(i)
      do while (slot > 0)
        old_len(i) = old_len(i) + 1
        old_list(i, old_len(i)) = slot
        slot = s%next_of(slot, i)
      end do
    end do
    call s%remap_bodies(new_index, n_new, dropped, n_dropped)
    kept_ok = s%check()
    drop_ok = .true.
    do slot = 1, n_slots_before
      if (old_a(slot) == 0) cycle
      if (new_index(old_a(slot)) > 0 .and. new_index(old_b(slot)) > 0) then
        kept_ok = kept_ok .and. s%a(slot) == new_index(old_a(slot)) .and. s%b(slot) == new_index(old_b(slot)) .and. &
                  s%gap(slot) == gap_of(slot) .and. all(s%stamp(:, slot) == [int(slot, i8), -int(slot, i8)])
        if (any(dropped(1:n_dropped) == slot)) drop_ok = .false.
      else
        if (s%a(slot) /= 0 .or. .not. any(dropped(1:n_dropped) == slot)) drop_ok = .false.
      end if
    end do
    ! every body's list: its old list without the dropped pairs, in the same order
    order_ok = .true.
    do j = 1, n_new
      i = old_of(j)
      slot = s%head(j)
      if (i == 0) then
        if (slot /= 0) order_ok = .false.
        cycle
      end if
      do k = 1, old_len(i)
        if (any(dropped(1:n_dropped) == old_list(i, k))) cycle
        if (slot /= old_list(i, k)) order_ok = .false.
        if (slot > 0) slot = s%next_of(slot, j)
      end do
      if (slot /= 0) order_ok = .false.
    end do
    call check(kept_ok, 'store renumbered: lists consistent, kept pairs renamed with their certificates')
    call check(drop_ok, 'store renumbered: exactly the pairs with a body that left are dropped and listed')
    call check(order_ok, 'store renumbered: each body keeps the order of its remaining pairs')
    j = findloc(old_of, 0, 1, back=.true.)
    slot = s%add(j, new_index(maxloc(new_index, 1)), 1000_i8, gid(maxloc(new_index, 1)))
    call check(s%check() .and. s%degree(j) == 1, 'store renumbered: an arrival''s pair added')
    ! grid: regions kept for the bodies that stay, nobody else listed until placed
    call g%init(0.1_dp, n, err)
    do i = 1, n
      call random_region(rng, lower(:, i), upper(:, i))
      call g%place(i, lower(:, i), upper(:, i), err)
    end do
    call g%remap_bodies(new_index, n_new)
    ok = err%ok()
    do j = 1, n_new
      i = old_of(j)
      if (i == 0) then
        if (g%placed(j)) ok = .false.
        cycle
      end if
      call g%query(j, found, n_found, n_new)
      expected = 0
      do k = 1, n
        if (k == i .or. new_index(k) == 0) cycle
        if (all(lower(:, k) <= upper(:, i)) .and. all(lower(:, i) <= upper(:, k))) expected = expected + 1
      end do
      if (n_found /= expected) ok = .false.
      do k = 1, n_found
        if (old_of(found(k)) == 0) then
          ok = .false.
        else if (.not. (all(lower(:, old_of(found(k))) <= upper(:, i)) .and. &
                        all(lower(:, i) <= upper(:, old_of(found(k)))))) then
          ok = .false.
        end if
      end do
    end do
    call check(ok, 'grid renumbered: queries return exactly the overlapping regions of bodies that stayed, renamed')
    j = findloc(old_of, 0, 1)
    if (j > 0) then
      i = findloc(new_index > 0, .true., 1)
      call g%place(j, g%region(1:3, new_index(i)), g%region(4:6, new_index(i)), err)
      call g%query(j, found, n_found, n_new)
      call check(any(found(1:n_found) == new_index(i)), 'grid renumbered: an arrival placed finds its neighbours')
    end if
    call appended_only()
  end subroutine renumbering

  !> Bodies only appended (a light window start's new ghosts: new_index the identity on the
  !> old rows): the store's fast path keeps every slot, certificate and list as it was.
  subroutine appended_only()
    integer, parameter :: n = 50, n_more = 7
    type(pair_store_t) :: s
    type(random_stream_t) :: rng
    integer, allocatable :: dropped(:), old_a(:), old_b(:), old_next(:, :), old_head(:), old_degree(:)
    real(dp), allocatable :: old_gap(:)
    integer :: i, slot, step, n_dropped, identity(n)
    integer(i8) :: gid(n + n_more)
    logical :: ok
    call rng%init(41)
    gid = [(int(5 * i + 2, i8), i=1, n + n_more)]
    call s%init(n, 8)
    call add_random_pairs(s, rng, gid(1:n), 300)
    do step = 1, 40      ! some free slots too
      slot = 1 + int(rng%uniform() * s%n_slots)
      if (s%a(slot) /= 0) call s%remove(slot)
    end do
    old_a = s%a(1:s%n_slots)
    old_b = s%b(1:s%n_slots)
    old_gap = s%gap(1:s%n_slots)
    old_next = s%next(:, 1:s%n_slots)
    old_head = s%head(1:n)
    old_degree = s%degree(1:n)
    identity = [(i, i=1, n)]
    call s%remap_bodies(identity, n + n_more, dropped, n_dropped)
    ok = s%check() .and. n_dropped == 0 .and. size(s%head) == n + n_more
    ok = ok .and. all(s%a(1:size(old_a)) == old_a) .and. all(s%b(1:size(old_b)) == old_b) .and. &
         all(s%gap(1:size(old_gap)) == old_gap) .and. all(s%next(:, 1:size(old_a)) == old_next)
    ok = ok .and. all(s%head(1:n) == old_head) .and. all(s%degree(1:n) == old_degree) .and. &
         all(s%head(n + 1:) == 0) .and. all(s%degree(n + 1:) == 0)
    call check(ok, 'store, bodies only appended: every slot, certificate and list as it was, the new bodies empty')
    slot = s%add(n + 1, 1, gid(n + 1), gid(1))
    call check(s%check() .and. s%degree(n + 1) == 1 .and. s%find(1, n + 1) == slot, &
               'store, bodies only appended: a pair of a new body added')
    ! the queue of box crossings, handles only appended (its fast path keeps the heap as it
    ! is): the same entries in the same order as a queue that never was renumbered, and room
    ! for the new handles beyond the old capacity
    block
      type(event_queue_t) :: q, ref
      integer :: h, h_ref
      real(dp) :: t, t_ref
      call q%init(n)
      call ref%init(n + n_more)
      do i = 1, n
        if (rng%uniform() < 0.2_dp) cycle     ! (some bodies have no crossing queued)
        t = real(int(rng%uniform()*4.0_dp), dp)   ! (equal times: the ties decide)
        call q%set(i, t, gid(i), 0_i8)
        call ref%set(i, t, gid(i), 0_i8)
      end do
      call q%remap_handles(identity, n + n_more)
      ok = q%check_heap() .and. q%n == ref%n .and. all(q%heap(1:q%n) == ref%heap(1:ref%n)) .and. &
           size(q%pos) >= n + n_more
      call q%set(n + n_more, -1.0_dp, gid(n + n_more), 0_i8)
      call ref%set(n + n_more, -1.0_dp, gid(n + n_more), 0_i8)
      do while (.not. ref%empty())
        call q%pop(h, t)
        call ref%pop(h_ref, t_ref)
        if (h /= h_ref .or. t /= t_ref) ok = .false.
      end do
      call check(ok .and. q%empty(), 'queue, handles only appended: the heap as it was, room and order for the new ones')
    end block
  end subroutine appended_only

  !> Up to `tries` random pairs of bodies 1..size(gid) with distinct certificates (gap and
  !> stamp from the slot).
  subroutine add_random_pairs(s, rng, gid, tries)
    type(pair_store_t), intent(inout) :: s
    type(random_stream_t), intent(inout) :: rng
    integer(i8), intent(in) :: gid(:)
    integer, intent(in) :: tries
    integer :: step, i, j, slot
    do step = 1, tries
      i = 1 + int(rng%uniform() * size(gid))
      j = 1 + int(rng%uniform() * size(gid))
      if (i == j) cycle
      if (s%find(i, j) > 0) cycle
      slot = s%add(i, j, gid(i), gid(j))
      s%gap(slot) = real(slot, dp) + 0.5_dp
      s%stamp(:, slot) = [int(slot, i8), -int(slot, i8)]
    end do
  end subroutine add_random_pairs

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
