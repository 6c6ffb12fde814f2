!> The candidate pairs of the local event loop and what is known about each between events
!> (a kinetic data structure, docs/architecture.md "Local events").
!>
!> A pair slot holds two bodies (local indices, the one with the lower global id first, so
!> that a pair is evaluated the same way wherever its bodies are stored), the time of its
!> last closest-point query with the gap and normal found there, the certified time up to
!> which the pair cannot reach its aim (its next action: query again, an impact, or joining
!> an island), and the trajectory versions of both bodies that certificate was computed
!> with. A certificate is current only while both versions are: a body whose anchor changes
!> gets a new version, and every pair of it is evaluated again.
!>
!> Each body lists its pairs (an intrusive singly linked list through the slots: a body has
!> a few tens of pairs at most, so walking is cheaper than a hash). Freed slots are reused.
!>
!> An undo journal (start_journal, roll_back, stop_journal: a cross-rank window's save,
!> docs/architecture.md step 4) keeps the first change of every slot, body list head and
!> free-list entry since its start. The store's own procedures note their writes; a caller
!> writing a slot's fields (a certificate) calls touch(slot) first.
module pair_store
  use kinds, only: dp, i8
  use row_journal, only: row_journal_t
  use sorting, only: keeps_first
  implicit none
  private
  public :: pair_store_t
  public :: ACTION_NONE, ACTION_QUERY, ACTION_IMPACT, ACTION_ENTER

  integer, parameter :: ACTION_NONE = 0     !< no event: static or asleep pair, or nothing can happen
  integer, parameter :: ACTION_QUERY = 1    !< the certificate ends: measure the pair again
  integer, parameter :: ACTION_IMPACT = 2   !< the pair reaches contact: an impact
  integer, parameter :: ACTION_ENTER = 3    !< an inelastic pair comes within reach of the contact pass

  type :: pair_store_t
    integer :: n_slots = 0                      !< slots ever used (high-water mark)
    integer :: n_live = 0                       !< pairs held now
    integer, allocatable :: a(:), b(:)          !< local body indices, gid(a) < gid(b); 0: free slot
    integer, allocatable :: next(:, :)          !< (2, slot): next slot in the list of a (1) and of b (2)
    integer, allocatable :: head(:)             !< per body: its first pair slot (0: none)
    integer, allocatable :: degree(:)           !< per body: pairs held
    integer, allocatable :: free_slots(:)
    integer :: n_free = 0
    integer(i8), allocatable :: stamp(:, :)     !< (2, slot): versions of a and b the certificate used
    real(dp), allocatable :: t_query(:)         !< time of the last closest-point query [s]
    real(dp), allocatable :: gap(:)             !< gap there [m] (a lower bound if far)
    real(dp), allocatable :: normal(:, :)       !< (3, slot) normal there, from a to b
    logical, allocatable :: far(:)              !< gap is only the bounding-volume lower bound
    real(dp), allocatable :: t_due(:)           !< time of the next action [s]
    real(dp), allocatable :: certified_until(:) !< the certificate holds up to here [s] (the audit's check)
    integer, allocatable :: action(:)           !< ACTION_*
    logical, allocatable :: in_pass(:)          !< the contact pass of the island step solved it
    !> the undo journal: slot rows, body rows (head, degree), free-list positions, and the
    !> counts at its start
    type(row_journal_t) :: slot_journal, body_journal, free_journal
    integer :: journal_counts(3) = 0
  contains
    procedure :: init => store_init
    procedure :: free => store_free
    procedure :: add => store_add
    procedure :: remove => store_remove
    procedure :: find => store_find
    procedure :: next_of => store_next_of
    procedure :: partner => store_partner
    procedure :: current => store_current
    procedure :: grow_bodies => store_grow_bodies
    procedure :: remap_bodies => store_remap_bodies
    procedure :: check => store_check
    procedure :: touch => store_touch
    procedure :: start_journal => store_start_journal
    procedure :: roll_back => store_roll_back
    procedure :: stop_journal => store_stop_journal
  end type pair_store_t

  !> words of a slot's row in the journal: a, b, next(2), action, far, in_pass, stamp(2),
  !> t_query, gap, normal(3), t_due, certified_until
  integer, parameter :: slot_words = 16

contains

  subroutine store_init(self, n_bodies, capacity)
    class(pair_store_t), intent(inout) :: self
    integer, intent(in) :: n_bodies, capacity
    integer :: c
    call self%free()
    call self%stop_journal()
    c = max(capacity, 16)
    allocate (self%a(c), self%b(c), self%next(2, c), self%free_slots(c), self%stamp(2, c), self%t_query(c), &
              self%gap(c), self%normal(3, c), self%far(c), self%t_due(c), self%action(c), self%in_pass(c), &
              self%certified_until(c))
    allocate (self%head(max(n_bodies, 1)), self%degree(max(n_bodies, 1)))
    self%a = 0
    self%b = 0
    self%head = 0
    self%degree = 0
    self%n_slots = 0
    self%n_live = 0
    self%n_free = 0
  end subroutine store_init

  subroutine store_free(self)
    class(pair_store_t), intent(inout) :: self
    if (allocated(self%a)) deallocate (self%a, self%b, self%next, self%free_slots, self%stamp, self%t_query, &
                                       self%gap, self%normal, self%far, self%t_due, self%action, self%in_pass, &
                                       self%certified_until)
    if (allocated(self%head)) deallocate (self%head, self%degree)
    self%n_slots = 0
    self%n_live = 0
    self%n_free = 0
  end subroutine store_free

  !> Room for bodies up to n (a body list that grew: ghosts, woken bodies).
  subroutine store_grow_bodies(self, n)
    class(pair_store_t), intent(inout) :: self
    integer, intent(in) :: n
    integer, allocatable :: head(:), degree(:)
    if (size(self%head) >= n) return
    allocate (head(n), degree(n))
    head = 0
    degree = 0
    head(1:size(self%head)) = self%head
    degree(1:size(self%degree)) = self%degree
    call move_alloc(head, self%head)
    call move_alloc(degree, self%degree)
  end subroutine store_grow_bodies

  !> The bodies were renumbered (a migration: docs/architecture.md, "Migration"): body i is
  !> now new_index(i), 0 if it left, of n_bodies. Every pair of two bodies that stayed keeps
  !> its slot and everything in it (certificate, stamp, gap, action: bodies keep their
  !> global ids, so a stays the lower one); a pair with a body that left is dropped, its slot
  !> freed and listed in dropped(1:n_dropped), in increasing slot order (their queue entries
  !> are the caller's). Each body's list keeps the order of its remaining pairs. O(pairs),
  !> O(bodies) when bodies were only appended.
  subroutine store_remap_bodies(self, new_index, n_bodies, dropped, n_dropped)
    class(pair_store_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n_bodies
    integer, allocatable, intent(out) :: dropped(:)
    integer, intent(out) :: n_dropped
    integer, allocatable :: head(:), degree(:), tail(:), next(:, :)
    integer :: i, slot, ni, old_a, old_b
    logical, allocatable :: keep(:)
    call self%stop_journal()     ! (renumbered rows: a journal kept before means nothing now)
    ! bodies only appended (a light window start's new ghosts): every pair and list stays as
    ! it is, which the general path below would also give, in O(pairs) (5-8 ms a window at
    ! 50,000 bodies a rank, where this is O(bodies appended))
    if (n_bodies >= size(new_index) .and. size(new_index) >= size(self%head) .and. &
        keeps_first(new_index, size(new_index))) then
      allocate (dropped(16))
      n_dropped = 0
      call self%grow_bodies(max(n_bodies, 1))
      return
    end if
    allocate (keep(self%n_slots), head(max(n_bodies, 1)), degree(max(n_bodies, 1)), tail(max(n_bodies, 1)), &
              next(2, size(self%a)), dropped(16))
    head = 0
    degree = 0
    tail = 0
    next = 0
    n_dropped = 0
    do slot = 1, self%n_slots
      keep(slot) = .false.
      if (self%a(slot) == 0) cycle
      keep(slot) = new_index(self%a(slot)) > 0 .and. new_index(self%b(slot)) > 0
    end do
    ! the lists again, each in its old order, through the kept slots only (the old links are
    ! read while the new ones are written apart)
    do i = 1, size(new_index)
      ni = new_index(i)
      if (ni == 0 .or. i > size(self%head)) cycle
      slot = self%head(i)
      do while (slot > 0)
        if (keep(slot)) then
          if (tail(ni) == 0) then
            head(ni) = slot
          else if (next_side(tail(ni), ni) == 1) then
            next(1, tail(ni)) = slot
          else
            next(2, tail(ni)) = slot
          end if
          tail(ni) = slot
          degree(ni) = degree(ni) + 1
        end if
        slot = self%next_of(slot, i)
      end do
    end do
    do slot = 1, self%n_slots
      if (self%a(slot) == 0) cycle
      old_a = self%a(slot)
      old_b = self%b(slot)
      if (keep(slot)) then
        self%a(slot) = new_index(old_a)
        self%b(slot) = new_index(old_b)
      else
        self%a(slot) = 0
        self%b(slot) = 0
        if (self%n_free == size(self%free_slots)) call grow_free(self)
        self%n_free = self%n_free + 1
        self%free_slots(self%n_free) = slot
        self%n_live = self%n_live - 1
        if (n_dropped == size(dropped)) call grow_int(dropped, 2*size(dropped))
        n_dropped = n_dropped + 1
        dropped(n_dropped) = slot
      end if
    end do
    self%next = next
    call move_alloc(head, self%head)
    call move_alloc(degree, self%degree)
  contains
    !> Which of the new links of slot s (1: a's, 2: b's) belongs to new body nb's list.
    integer function next_side(s, nb)
      integer, intent(in) :: s, nb
      next_side = 2
      if (new_index(self%a(s)) == nb) next_side = 1
    end function next_side
  end subroutine store_remap_bodies

  !> A new pair of bodies i and j (gid_i, gid_j: their global ids; the lower one becomes a).
  !> Returns its slot. The caller makes sure the pair is not held yet (find).
  integer function store_add(self, i, j, gid_i, gid_j) result(slot)
    class(pair_store_t), intent(inout) :: self
    integer, intent(in) :: i, j
    integer(i8), intent(in) :: gid_i, gid_j
    integer :: lo, hi
    if (gid_i < gid_j) then
      lo = i; hi = j
    else
      lo = j; hi = i
    end if
    if (self%n_free > 0) then
      slot = self%free_slots(self%n_free)
      self%n_free = self%n_free - 1
    else
      if (self%n_slots == size(self%a)) call grow_slots(self)
      self%n_slots = self%n_slots + 1
      slot = self%n_slots
    end if
    call self%touch(slot)
    call touch_body(self, lo)
    call touch_body(self, hi)
    self%a(slot) = lo
    self%b(slot) = hi
    self%next(1, slot) = self%head(lo)
    self%head(lo) = slot
    self%next(2, slot) = self%head(hi)
    self%head(hi) = slot
    self%degree(lo) = self%degree(lo) + 1
    self%degree(hi) = self%degree(hi) + 1
    self%stamp(:, slot) = -1
    self%t_query(slot) = -huge(1.0_dp)
    self%gap(slot) = huge(1.0_dp)
    self%normal(:, slot) = 0.0_dp
    self%far(slot) = .true.
    self%t_due(slot) = huge(1.0_dp)
    self%certified_until(slot) = -huge(1.0_dp)
    self%action(slot) = ACTION_NONE
    self%in_pass(slot) = .false.
    self%n_live = self%n_live + 1
  end function store_add

  !> Drops the pair in slot (its queue entry is the caller's).
  subroutine store_remove(self, slot)
    class(pair_store_t), intent(inout) :: self
    integer, intent(in) :: slot
    call self%touch(slot)
    call touch_body(self, self%a(slot))
    call touch_body(self, self%b(slot))
    call unlink(self, self%a(slot), slot)
    call unlink(self, self%b(slot), slot)
    self%degree(self%a(slot)) = self%degree(self%a(slot)) - 1
    self%degree(self%b(slot)) = self%degree(self%b(slot)) - 1
    self%a(slot) = 0
    self%b(slot) = 0
    if (self%n_free == size(self%free_slots)) call grow_free(self)
    self%n_free = self%n_free + 1
    call touch_free(self, self%n_free)
    self%free_slots(self%n_free) = slot
    self%n_live = self%n_live - 1
  end subroutine store_remove

  !> The slot of the pair (i, j) in either order, 0 if not held.
  pure integer function store_find(self, i, j) result(slot)
    class(pair_store_t), intent(in) :: self
    integer, intent(in) :: i, j
    integer :: first, other
    ! walk the shorter list
    if (self%degree(i) <= self%degree(j)) then
      first = i; other = j
    else
      first = j; other = i
    end if
    slot = self%head(first)
    do while (slot > 0)
      if (self%a(slot) == other .or. self%b(slot) == other) return
      slot = self%next_of(slot, first)
    end do
  end function store_find

  !> The slot after `slot` in body i's list (0 at the end).
  pure integer function store_next_of(self, slot, i) result(next_slot)
    class(pair_store_t), intent(in) :: self
    integer, intent(in) :: slot, i
    if (self%a(slot) == i) then
      next_slot = self%next(1, slot)
    else
      next_slot = self%next(2, slot)
    end if
  end function store_next_of

  !> The other body of the pair in slot.
  pure integer function store_partner(self, slot, i) result(j)
    class(pair_store_t), intent(in) :: self
    integer, intent(in) :: slot, i
    if (self%a(slot) == i) then
      j = self%b(slot)
    else
      j = self%a(slot)
    end if
  end function store_partner

  !> Was slot's certificate computed with the trajectory versions the bodies have now?
  pure logical function store_current(self, slot, version) result(ok)
    class(pair_store_t), intent(in) :: self
    integer, intent(in) :: slot
    integer(i8), intent(in) :: version(:)    !< per body
    ok = self%stamp(1, slot) == version(self%a(slot)) .and. self%stamp(2, slot) == version(self%b(slot))
  end function store_current

  !> The lists and the counts agree (tests): every live slot is in both of its bodies' lists
  !> exactly once, and no list holds a free slot.
  pure logical function store_check(self) result(ok)
    class(pair_store_t), intent(in) :: self
    integer :: i, slot, seen, live
    ok = .true.
    live = 0
    do i = 1, size(self%head)
      seen = 0
      slot = self%head(i)
      do while (slot > 0)
        if (self%a(slot) /= i .and. self%b(slot) /= i) then
          ok = .false.
          return
        end if
        seen = seen + 1
        if (seen > self%n_slots) then
          ok = .false.
          return
        end if
        slot = self%next_of(slot, i)
      end do
      if (seen /= self%degree(i)) ok = .false.
      live = live + seen
    end do
    if (live /= 2*self%n_live) ok = .false.
    if (count(self%a(1:self%n_slots) > 0) /= self%n_live) ok = .false.
  end function store_check

  !> While journaling: slot's row is about to change; the first time since the journal's
  !> start, it is kept as it is now.
  subroutine store_touch(self, slot)
    class(pair_store_t), intent(inout) :: self
    integer, intent(in) :: slot
    integer :: m
    integer(i8), parameter :: mold = 0_i8
    if (.not. self%slot_journal%active) return
    m = self%slot_journal%keep(slot)
    if (m == 0) return
    associate (w => self%slot_journal%words(:, m))
      w(1) = self%a(slot)
      w(2) = self%b(slot)
      w(3:4) = self%next(:, slot)
      w(5) = self%action(slot)
      w(6) = merge(1_i8, 0_i8, self%far(slot))
      w(7) = merge(1_i8, 0_i8, self%in_pass(slot))
      w(8:9) = self%stamp(:, slot)
      w(10) = transfer(self%t_query(slot), mold)
      w(11) = transfer(self%gap(slot), mold)
      w(12:14) = transfer(self%normal(:, slot), mold, 3)
      w(15) = transfer(self%t_due(slot), mold)
      w(16) = transfer(self%certified_until(slot), mold)
    end associate
  end subroutine store_touch

  !> While journaling: body i's list head and degree are about to change.
  subroutine touch_body(self, i)
    type(pair_store_t), intent(inout) :: self
    integer, intent(in) :: i
    integer :: m
    if (.not. self%body_journal%active) return
    m = self%body_journal%keep(i)
    if (m == 0) return
    self%body_journal%words(1, m) = self%head(i)
    self%body_journal%words(2, m) = self%degree(i)
  end subroutine touch_body

  !> While journaling: position p of the free list is about to be written.
  subroutine touch_free(self, p)
    type(pair_store_t), intent(inout) :: self
    integer, intent(in) :: p
    integer :: m
    if (.not. self%free_journal%active) return
    m = self%free_journal%keep(p)
    if (m == 0) return
    self%free_journal%words(1, m) = self%free_slots(p)
  end subroutine touch_free

  !> From now on the first change of each slot, list head and free-list entry is kept, until
  !> roll_back or stop_journal (the store as it is now: the state roll_back returns to).
  subroutine store_start_journal(self)
    class(pair_store_t), intent(inout) :: self
    call self%slot_journal%start(size(self%a), slot_words)
    call self%body_journal%start(size(self%head), 2)
    call self%free_journal%start(size(self%free_slots), 1)
    self%journal_counts = [self%n_slots, self%n_live, self%n_free]
  end subroutine store_start_journal

  !> No more journal (what it kept is dropped).
  subroutine store_stop_journal(self)
    class(pair_store_t), intent(inout) :: self
    call self%slot_journal%stop()
    call self%body_journal%stop()
    call self%free_journal%stop()
  end subroutine store_stop_journal

  !> The store back as it was at start_journal, bit for bit in every slot, list and free-list
  !> entry up to the counts of then (slots beyond n_slots are never read); the journal goes
  !> on from there. O(changes since the start).
  subroutine store_roll_back(self)
    class(pair_store_t), intent(inout) :: self
    integer :: m, slot, i
    if (.not. self%slot_journal%active) return
    do m = 1, self%slot_journal%n
      slot = self%slot_journal%ids(m)
      associate (w => self%slot_journal%words(:, m))
        self%a(slot) = int(w(1))
        self%b(slot) = int(w(2))
        self%next(:, slot) = int(w(3:4))
        self%action(slot) = int(w(5))
        self%far(slot) = w(6) /= 0
        self%in_pass(slot) = w(7) /= 0
        self%stamp(:, slot) = w(8:9)
        self%t_query(slot) = transfer(w(10), 1.0_dp)
        self%gap(slot) = transfer(w(11), 1.0_dp)
        self%normal(:, slot) = transfer(w(12:14), 1.0_dp, 3)
        self%t_due(slot) = transfer(w(15), 1.0_dp)
        self%certified_until(slot) = transfer(w(16), 1.0_dp)
      end associate
    end do
    do m = 1, self%body_journal%n
      i = self%body_journal%ids(m)
      self%head(i) = int(self%body_journal%words(1, m))
      self%degree(i) = int(self%body_journal%words(2, m))
    end do
    do m = 1, self%free_journal%n
      self%free_slots(self%free_journal%ids(m)) = int(self%free_journal%words(1, m))
    end do
    self%n_slots = self%journal_counts(1)
    self%n_live = self%journal_counts(2)
    self%n_free = self%journal_counts(3)
    call self%slot_journal%clear()
    call self%body_journal%clear()
    call self%free_journal%clear()
  end subroutine store_roll_back

  subroutine unlink(self, i, slot)
    type(pair_store_t), intent(inout) :: self
    integer, intent(in) :: i, slot
    integer :: s, previous
    previous = 0
    s = self%head(i)
    do while (s > 0)
      if (s == slot) then
        if (previous == 0) then
          self%head(i) = self%next_of(s, i)
        else if (self%a(previous) == i) then
          call self%touch(previous)
          self%next(1, previous) = self%next_of(s, i)
        else
          call self%touch(previous)
          self%next(2, previous) = self%next_of(s, i)
        end if
        return
      end if
      previous = s
      s = self%next_of(s, i)
    end do
  end subroutine unlink

  subroutine grow_slots(self)
    type(pair_store_t), intent(inout) :: self
    integer :: c
    c = 2*size(self%a)
    call grow_int(self%a, c)
    call grow_int(self%b, c)
    call grow_int2(self%next, c)
    call grow_i82(self%stamp, c)
    call grow_real(self%t_query, c)
    call grow_real(self%gap, c)
    call grow_real2(self%normal, c)
    call grow_logical(self%far, c)
    call grow_real(self%t_due, c)
    call grow_real(self%certified_until, c)
    call grow_int(self%action, c)
    call grow_logical(self%in_pass, c)
  end subroutine grow_slots

  subroutine grow_free(self)
    type(pair_store_t), intent(inout) :: self
    call grow_int(self%free_slots, 2*size(self%free_slots))
  end subroutine grow_free

  subroutine grow_int(x, c)
    integer, allocatable, intent(inout) :: x(:)
    integer, intent(in) :: c
    integer, allocatable :: y(:)
    allocate (y(c))
    y = 0
    y(1:size(x)) = x
    call move_alloc(y, x)
  end subroutine grow_int

  subroutine grow_int2(x, c)
    integer, allocatable, intent(inout) :: x(:, :)
    integer, intent(in) :: c
    integer, allocatable :: y(:, :)
    allocate (y(size(x, 1), c))
    y = 0
    y(:, 1:size(x, 2)) = x
    call move_alloc(y, x)
  end subroutine grow_int2

  subroutine grow_i82(x, c)
    integer(i8), allocatable, intent(inout) :: x(:, :)
    integer, intent(in) :: c
    integer(i8), allocatable :: y(:, :)
    allocate (y(size(x, 1), c))
    y = 0
    y(:, 1:size(x, 2)) = x
    call move_alloc(y, x)
  end subroutine grow_i82

  subroutine grow_real(x, c)
    real(dp), allocatable, intent(inout) :: x(:)
    integer, intent(in) :: c
    real(dp), allocatable :: y(:)
    allocate (y(c))
    y = 0.0_dp
    y(1:size(x)) = x
    call move_alloc(y, x)
  end subroutine grow_real

  subroutine grow_real2(x, c)
    real(dp), allocatable, intent(inout) :: x(:, :)
    integer, intent(in) :: c
    real(dp), allocatable :: y(:, :)
    allocate (y(size(x, 1), c))
    y = 0.0_dp
    y(:, 1:size(x, 2)) = x
    call move_alloc(y, x)
  end subroutine grow_real2

  subroutine grow_logical(x, c)
    logical, allocatable, intent(inout) :: x(:)
    integer, intent(in) :: c
    logical, allocatable :: y(:)
    allocate (y(c))
    y = .false.
    y(1:size(x)) = x
    call move_alloc(y, x)
  end subroutine grow_logical

end module pair_store
