!> The priority queue of the local event loop: an indexed binary min-heap of handles.
!>
!> Each handle (a pair slot, a body, an island: the caller's numbering, 1-based) is in the
!> queue at most once, with a time and two integer tie-breaks (global ids), so that events
!> at equal times are taken in an order that depends only on the bodies involved, never on
!> where they are stored or when they were queued. Setting the time of a handle already in
!> the queue moves it (decrease or increase key): no stale entries pile up, and a handle
!> whose certificate changed is simply set again. O(log n) per operation.
!>
!> Order: (time, tie(1), tie(2), handle) lexicographically. Measured against a calendar
!> queue in docs/architecture.md ("The queue").
!>
!> An undo journal (start_journal, roll_back, stop_journal: a cross-rank window's save)
!> keeps the first change of each handle's entry (time, tie-breaks, and whether it was in
!> the queue) since its start, not the heap positions the sifts move: the order is total
!> (the handle is its last tie-break), so the queue made again from the entries pops in the
!> same order whatever its layout, and a roll back rebuilds the heap (Floyd, O(n)). A
!> journal of positions kept every handle a sift moved, 20 a set in a heap of a million
!> pairs: 3% of a two-rank run of 100,000 spheres, for the few windows rolled back.
module event_queue
  use kinds, only: dp, i8
  use row_journal, only: row_journal_t
  use sorting, only: keeps_first
  implicit none
  private
  public :: event_queue_t

  type :: event_queue_t
    integer :: n = 0                          !< handles in the queue
    integer, allocatable :: heap(:)           !< handles by heap position 1..n
    integer, allocatable :: pos(:)            !< heap position of each handle, 0 if absent
    real(dp), allocatable :: time(:)          !< per handle: its event time [s]
    integer(i8), allocatable :: tie(:, :)     !< per handle: (2) tie-breaks
    !> per handle: its heap position (0: not in the queue; only that is used), time, tie(2)
    type(row_journal_t) :: journal
  contains
    procedure :: init => queue_init
    procedure :: free => queue_free
    procedure :: set => queue_set
    procedure :: remove => queue_remove
    procedure :: holds => queue_holds
    procedure :: empty => queue_empty
    procedure :: top => queue_top
    procedure :: top_time => queue_top_time
    procedure :: pop => queue_pop
    procedure :: time_of => queue_time_of
    procedure :: check_heap => queue_check_heap
    procedure :: remap_handles => queue_remap_handles
    procedure :: start_journal => queue_start_journal
    procedure :: roll_back => queue_roll_back
    procedure :: stop_journal => queue_stop_journal
  end type event_queue_t

contains

  !> capacity: handles expected (the queue grows beyond it as needed).
  subroutine queue_init(self, capacity)
    class(event_queue_t), intent(inout) :: self
    integer, intent(in) :: capacity
    call self%free()
    call self%journal%stop()
    allocate (self%heap(max(capacity, 16)), self%pos(max(capacity, 16)), self%time(max(capacity, 16)), &
              self%tie(2, max(capacity, 16)))
    self%pos = 0
    self%n = 0
  end subroutine queue_init

  subroutine queue_free(self)
    class(event_queue_t), intent(inout) :: self
    if (allocated(self%heap)) deallocate (self%heap, self%pos, self%time, self%tie)
    self%n = 0
  end subroutine queue_free

  pure logical function queue_empty(self)
    class(event_queue_t), intent(in) :: self
    queue_empty = self%n == 0
  end function queue_empty

  pure logical function queue_holds(self, handle)
    class(event_queue_t), intent(in) :: self
    integer, intent(in) :: handle
    queue_holds = .false.
    if (.not. allocated(self%pos)) return
    if (handle < 1 .or. handle > size(self%pos)) return
    queue_holds = self%pos(handle) > 0
  end function queue_holds

  !> The handle with the earliest event (0 if empty).
  pure integer function queue_top(self)
    class(event_queue_t), intent(in) :: self
    queue_top = 0
    if (self%n > 0) queue_top = self%heap(1)
  end function queue_top

  !> The earliest event time, huge() if empty [s].
  pure real(dp) function queue_top_time(self)
    class(event_queue_t), intent(in) :: self
    queue_top_time = huge(1.0_dp)
    if (self%n > 0) queue_top_time = self%time(self%heap(1))
  end function queue_top_time

  !> The time handle is queued at, huge() if absent [s].
  pure real(dp) function queue_time_of(self, handle)
    class(event_queue_t), intent(in) :: self
    integer, intent(in) :: handle
    queue_time_of = huge(1.0_dp)
    if (self%holds(handle)) queue_time_of = self%time(handle)
  end function queue_time_of

  !> Puts handle in the queue at time t with tie-breaks (tie1, tie2), or moves it there.
  subroutine queue_set(self, handle, t, tie1, tie2)
    class(event_queue_t), intent(inout) :: self
    integer, intent(in) :: handle
    real(dp), intent(in) :: t
    integer(i8), intent(in) :: tie1, tie2
    integer :: p
    if (.not. allocated(self%heap)) call self%init(max(16, handle))
    if (handle > size(self%pos)) call grow(self, handle)
    call note(self, handle)
    p = self%pos(handle)
    if (p == 0) then
      if (self%n == size(self%heap)) call grow(self, size(self%pos))
      self%n = self%n + 1
      self%heap(self%n) = handle
      self%pos(handle) = self%n
      self%time(handle) = t
      self%tie(:, handle) = [tie1, tie2]
      call sift_up(self, self%n)
    else
      self%time(handle) = t
      self%tie(:, handle) = [tie1, tie2]
      call sift_up(self, p)
      call sift_down(self, self%pos(handle))
    end if
  end subroutine queue_set

  !> Takes handle out of the queue (nothing if absent).
  subroutine queue_remove(self, handle)
    class(event_queue_t), intent(inout) :: self
    integer, intent(in) :: handle
    integer :: p, last
    if (.not. self%holds(handle)) return
    p = self%pos(handle)
    last = self%heap(self%n)
    call note(self, handle)
    self%pos(handle) = 0
    self%n = self%n - 1
    if (p > self%n) return          ! it was the last one
    self%heap(p) = last
    self%pos(last) = p
    call sift_up(self, p)
    call sift_down(self, self%pos(last))
  end subroutine queue_remove

  !> Removes and returns the earliest handle (0 if empty) and its time.
  subroutine queue_pop(self, handle, t)
    class(event_queue_t), intent(inout) :: self
    integer, intent(out) :: handle
    real(dp), intent(out) :: t
    handle = self%top()
    t = huge(1.0_dp)
    if (handle == 0) return
    t = self%time(handle)
    call self%remove(handle)
  end subroutine queue_pop

  !> The handles were renumbered (the bodies of a rank after a migration): handle h is now
  !> new_index(h), 0 if it is gone; capacity: handles expected from now on. Every kept entry
  !> keeps its time and tie-breaks; the heap is rebuilt in place (Floyd, O(n)), since the
  !> handle is the order's last tie-break.
  subroutine queue_remap_handles(self, new_index, capacity)
    class(event_queue_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: capacity
    integer, allocatable :: heap(:)
    real(dp), allocatable :: time(:)
    integer(i8), allocatable :: tie(:, :)
    integer :: p, h, nh, n, c
    call self%journal%stop()     ! (renumbered handles: a journal kept before means nothing now)
    if (.not. allocated(self%heap)) then
      call self%init(capacity)
      return
    end if
    c = max(capacity, 16)
    ! handles only appended (a light window start's new ghosts): every entry keeps its place
    ! in the heap, and the arrays at least double when they grow (a rebuild was O(bodies) at
    ! every such start: 28 of the 888 samples of rank 0's light starts, 100,000 spheres on
    ! 2 ranks)
    if (keeps_first(new_index, size(new_index)) .and. all(self%heap(1:self%n) <= size(new_index))) then
      if (size(self%pos) < c) call grow(self, c)
      return
    end if
    do p = 1, self%n
      h = self%heap(p)
      if (h <= size(new_index)) c = max(c, new_index(h))
    end do
    allocate (heap(c), time(c), tie(2, c))
    n = 0
    do p = 1, self%n
      h = self%heap(p)
      nh = 0
      if (h <= size(new_index)) nh = new_index(h)
      if (nh == 0) cycle
      n = n + 1
      heap(n) = nh
      time(nh) = self%time(h)
      tie(:, nh) = self%tie(:, h)
    end do
    call move_alloc(heap, self%heap)
    call move_alloc(time, self%time)
    call move_alloc(tie, self%tie)
    deallocate (self%pos)
    allocate (self%pos(c))
    self%pos = 0
    call heapify(self, n)
  end subroutine queue_remap_handles

  !> heap(1:n) made a heap of the handles it holds (Floyd, O(n)), with their positions.
  subroutine heapify(self, n)
    type(event_queue_t), intent(inout) :: self
    integer, intent(in) :: n
    integer :: p
    self%n = n
    do p = 1, n
      self%pos(self%heap(p)) = p
    end do
    do p = n/2, 1, -1
      call sift_down(self, p)
    end do
  end subroutine heapify

  !> The heap property and the position index hold (tests).
  pure logical function queue_check_heap(self) result(ok)
    class(event_queue_t), intent(in) :: self
    integer :: p
    ok = .true.
    do p = 1, self%n
      if (self%pos(self%heap(p)) /= p) ok = .false.
      if (p > 1) then
        if (before(self, self%heap(p), self%heap(p/2))) ok = .false.
      end if
    end do
  end function queue_check_heap

  pure logical function before(self, h1, h2)
    type(event_queue_t), intent(in) :: self
    integer, intent(in) :: h1, h2
    if (self%time(h1) /= self%time(h2)) then
      before = self%time(h1) < self%time(h2)
    else if (self%tie(1, h1) /= self%tie(1, h2)) then
      before = self%tie(1, h1) < self%tie(1, h2)
    else if (self%tie(2, h1) /= self%tie(2, h2)) then
      before = self%tie(2, h1) < self%tie(2, h2)
    else
      before = h1 < h2
    end if
  end function before

  subroutine sift_up(self, start)
    type(event_queue_t), intent(inout) :: self
    integer, intent(in) :: start
    integer :: p, parent, h
    p = start
    h = self%heap(p)
    do while (p > 1)
      parent = p/2
      if (.not. before(self, h, self%heap(parent))) exit
      self%heap(p) = self%heap(parent)
      self%pos(self%heap(p)) = p
      p = parent
    end do
    self%heap(p) = h
    self%pos(h) = p
  end subroutine sift_up

  subroutine sift_down(self, start)
    type(event_queue_t), intent(inout) :: self
    integer, intent(in) :: start
    integer :: p, child, h
    p = start
    h = self%heap(p)
    do
      child = 2*p
      if (child > self%n) exit
      if (child < self%n) then
        if (before(self, self%heap(child + 1), self%heap(child))) child = child + 1
      end if
      if (.not. before(self, self%heap(child), h)) exit
      self%heap(p) = self%heap(child)
      self%pos(self%heap(p)) = p
      p = child
    end do
    self%heap(p) = h
    self%pos(h) = p
  end subroutine sift_down

  !> While journaling: handle h's entry is about to change; the first time since the
  !> journal's start, it is kept as it is now.
  subroutine note(self, h)
    type(event_queue_t), intent(inout) :: self
    integer, intent(in) :: h
    integer :: m
    if (.not. self%journal%active) return
    m = self%journal%keep(h)
    if (m == 0) return
    self%journal%words(1, m) = self%pos(h)
    self%journal%words(2, m) = transfer(self%time(h), 1_i8)
    self%journal%words(3:4, m) = self%tie(:, h)
  end subroutine note

  !> From now on the first change of each handle's entry is kept, until roll_back or
  !> stop_journal (the queue as it is now: the state roll_back returns to).
  subroutine queue_start_journal(self)
    class(event_queue_t), intent(inout) :: self
    if (.not. allocated(self%pos)) call self%init(16)
    call self%journal%start(size(self%pos), 4)
  end subroutine queue_start_journal

  !> No more journal (what it kept is dropped).
  subroutine queue_stop_journal(self)
    class(event_queue_t), intent(inout) :: self
    call self%journal%stop()
  end subroutine queue_stop_journal

  !> The queue back as it was at start_journal: the same handles in it with the same times
  !> and tie-breaks (so the same order of pops), the heap built again from them (Floyd,
  !> O(n)); the journal goes on from there.
  subroutine queue_roll_back(self)
    class(event_queue_t), intent(inout) :: self
    integer :: m, h, p, n
    if (.not. self%journal%active) return
    ! the handles in the queue now that kept no entry (unchanged since the start), then the
    ! kept ones that were in it
    n = 0
    do p = 1, self%n
      h = self%heap(p)
      self%pos(h) = 0
      if (h <= size(self%journal%kept)) then
        if (self%journal%kept(h)) cycle
      end if
      n = n + 1
      self%heap(n) = h
    end do
    do m = 1, self%journal%n
      h = self%journal%ids(m)
      self%time(h) = transfer(self%journal%words(2, m), 1.0_dp)
      self%tie(:, h) = self%journal%words(3:4, m)
      self%pos(h) = 0
      if (self%journal%words(1, m) == 0) cycle
      n = n + 1
      self%heap(n) = h
    end do
    call heapify(self, n)
    call self%journal%clear()
  end subroutine queue_roll_back

  !> Room for handles up to at least `needed` (doubling).
  subroutine grow(self, needed)
    type(event_queue_t), intent(inout) :: self
    integer, intent(in) :: needed
    integer, allocatable :: heap(:), pos(:)
    real(dp), allocatable :: time(:)
    integer(i8), allocatable :: tie(:, :)
    integer :: capacity, old
    old = size(self%pos)
    capacity = max(2*old, needed)
    allocate (heap(capacity), pos(capacity), time(capacity), tie(2, capacity))
    pos = 0
    heap(1:self%n) = self%heap(1:self%n)
    pos(1:old) = self%pos
    time(1:old) = self%time
    tie(:, 1:old) = self%tie
    call move_alloc(heap, self%heap)
    call move_alloc(pos, self%pos)
    call move_alloc(time, self%time)
    call move_alloc(tie, self%tie)
  end subroutine grow

end module event_queue
