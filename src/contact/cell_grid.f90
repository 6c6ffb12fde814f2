!> The moving broad phase of the local event loop: a bucket grid that bodies enter and
!> leave one at a time, instead of being rebuilt every step (bucket_grid, the global loop's).
!>
!> A body is *placed* with a region: its bounding box grown by a margin, which it is
!> guaranteed not to leave before its next placement (the event loop places it again when
!> its trajectory changes or when the margin is used up: a box crossing). It is listed in
!> every grid box its region touches; boxes are cubes of edge h (the smallest moving body's
!> extent, as in the global loop), held in an open-addressing hash table keyed by the
!> box's integer coordinates, each with a small list of bodies. Two bodies are candidates
!> while their regions overlap; a body whose region spans more than max_span boxes along
!> some axis (floors, walls, containers) is kept out of the boxes and tested by box overlap
!> against every body that queries, so it neither floods thousands of boxes nor shrinks
!> them. Placing and querying cost O(boxes of the region + bodies listed there).
!>
!> Where the scene's bodies are known to start (init's dense_lower, dense_upper), the
!> boxes of that block are slots of their own, numbered by their coordinates (slot 1 +
!> a + n1 (b + n2 c) of the block): no hash, no probing, no key compared, and neighbouring
!> boxes in neighbouring slots. The 100,000-sphere gas spends a fifth of its run in the
!> grid (placing, unplacing, querying 8 boxes a body), most of it in cache misses on the
!> hashed slots' keys and lists. Boxes outside the block (a body flying off, the halo of a
!> rank) go to the hash table behind it, so the block is only a speed-up: what a query
!> finds does not depend on it.
module cell_grid
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INPUT, ERR_NUMERIC
  use sorting, only: keeps_first
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private
  public :: cell_grid_t, cell_lists_t

  !> |box coordinate| limit, far from int64 overflow in floor() and +-1.
  real(dp), parameter :: MAX_BOX_COORD = 2.0_dp**60
  !> Bits of a box coordinate that enter its hash (2^30 * 8.4e7 * 3 < 2^63).
  integer(i8), parameter :: KEY_MASK = 2_i8**30 - 1_i8

  type :: cell_grid_t
    real(dp) :: h = 0.0_dp                      !< box edge [m]
    real(dp) :: inv_h = 0.0_dp
    integer :: max_span = 4                     !< larger regions are not listed in boxes
    logical, allocatable :: placed(:)           !< per body
    logical, allocatable :: large(:)            !< placed outside the boxes
    !> (6, body) region [m]: lower corner (1:3), upper (4:6), side by side (a candidate's
    !> overlap test reads both: one cache miss, not two)
    real(dp), allocatable :: region(:, :)
    integer(i8), allocatable :: lo(:, :), hi(:, :)      !< (3, body) box range of the region
    !> Slots 1..n_dense: the dense block's boxes (dense_lo + (0..dense_n - 1), x fastest),
    !> always in use; slots n_dense + 1 .. n_dense + table_size: the hash table.
    integer :: n_dense = 0
    integer(i8) :: dense_lo(3) = 0, dense_n(3) = 0
    integer :: table_size = 0                   !< hash slots (a power of two)
    integer :: n_used = 0                       !< hash slots holding a box (possibly empty)
    integer(i8), allocatable :: slot_key(:, :)  !< (3, slot) (hash slots only)
    logical, allocatable :: slot_used(:)
    !> Each box's list of bodies: list(LIST_N, slot) ids at pool(list(LIST_AT, slot) + 1 :
    !> ...), room for list(LIST_CAP, slot), the three side by side (one cache miss a box
    !> where three arrays made three: the loads of a box's count were most of inserting).
    !> The lists live in one pool instead of an allocatable per box (a
    !> descriptor of 64 bytes a slot and a malloc a list: 800 MB and 1.6 s of page faults
    !> for the table of 50,000 spheres with their ghosts): a list that outgrows its room
    !> moves to the pool's top with twice the room, and the pool is compacted when more
    !> than half of it is rooms no list uses.
    integer, allocatable :: list(:, :)          !< (3, slot)
    integer, allocatable :: pool(:)
    integer :: pool_top = 0                     !< pool entries handed out (rooms, used or not)
    integer :: pool_live = 0                    !< of them, rooms of lists in the table
    integer, allocatable :: large_ids(:)
    integer :: n_large = 0
    integer, allocatable :: mark(:)             !< query de-duplication, per body
    integer :: mark_stamp = 0
    integer(i8) :: placements = 0               !< placements so far (summary)
    !> The bodies placed or unplaced since start_journal (a cross-rank window's save): a
    !> restore from a copy without the table (swap_table) takes them out of the lists before
    !> the copy and puts them back at their restored ranges after it (restore_prepare,
    !> restore_finish): O(bodies moved in the window), not a table made again from all.
    logical :: journaling = .false.
    logical, allocatable :: touched(:)          !< per body
    integer, allocatable :: touched_ids(:)
    !> (ROW_WORDS, k): row touched_ids(k) (placed, large, lower, upper, lo, hi) as it was
    !> at its first change: restore_finish puts it back, so that a copy of the grid need
    !> not carry the per-body rows (6 MB for the 56,000 rows of a rank of a 100,000-sphere
    !> gas, copied at every window's save)
    integer(i8), allocatable :: touched_rows(:, :)
    integer :: n_touched = 0
  contains
    procedure :: init => cells_init
    procedure :: free => cells_free
    procedure :: place => cells_place
    procedure :: unplace => cells_unplace
    procedure :: query => cells_query
    procedure :: grow_bodies => cells_grow_bodies
    procedure :: remap_bodies => cells_remap_bodies
    procedure :: overlaps => cells_overlaps
    procedure :: swap_table => cells_swap_table
    procedure :: start_journal => cells_start_journal
    procedure :: restore_prepare => cells_restore_prepare
    procedure :: restore_finish => cells_restore_finish
    procedure :: stop_journal => cells_stop_journal
  end type cell_grid_t

  !> A grid's box table and per-body rows held apart from it (cell_grid_t swap_table): see
  !> restore_prepare and restore_finish.
  type :: cell_lists_t
    private
    integer, allocatable :: list(:, :), pool(:)
    integer(i8), allocatable :: slot_key(:, :)
    logical, allocatable :: slot_used(:)
    logical, allocatable :: placed(:), large(:), touched(:)
    real(dp), allocatable :: region(:, :)
    integer(i8), allocatable :: lo(:, :), hi(:, :), touched_rows(:, :)
    integer, allocatable :: mark(:)
    integer :: table_size = 0, n_used = 0, pool_top = 0, pool_live = 0
    integer, allocatable :: touched_ids(:)
    integer :: n_touched = 0
  end type cell_lists_t

  integer, parameter :: first_room = 4          !< room of a new box's list
  !> rows of cell_grid_t list: a box's count of bodies, where its list starts in the pool
  !> (0-based), its room there
  integer, parameter, public :: LIST_N = 1, LIST_AT = 2, LIST_CAP = 3
  integer, parameter :: ROW_WORDS = 14          !< a body's row in touched_rows

contains

  !> An empty grid of boxes of edge box_size [m] for n_bodies bodies. dense_lower,
  !> dense_upper [m]: a block of space to hold in dense slots (where the bodies start),
  !> taken if it has at most max_dense boxes (default: none; a speed-up only).
  subroutine cells_init(self, box_size, n_bodies, err, max_span, dense_lower, dense_upper, max_dense)
    class(cell_grid_t), intent(inout) :: self
    real(dp), intent(in) :: box_size
    integer, intent(in) :: n_bodies
    type(error_t), intent(inout) :: err
    integer, intent(in), optional :: max_span
    real(dp), intent(in), optional :: dense_lower(3), dense_upper(3)
    integer, intent(in), optional :: max_dense
    integer(i8) :: block_lo(3), block_n(3)
    integer :: n_slots
    call self%free()
    if (.not. ieee_is_finite(box_size) .or. box_size <= 0.0_dp) then
      call err%set(ERR_INPUT, 'cell grid: the box size must be finite and > 0')
      return
    end if
    self%h = box_size
    self%inv_h = 1.0_dp/box_size
    if (present(max_span)) self%max_span = max(1, max_span)
    allocate (self%placed(n_bodies), self%large(n_bodies), self%region(6, n_bodies), &
              self%lo(3, n_bodies), self%hi(3, n_bodies), self%mark(n_bodies))
    self%placed = .false.
    self%large = .false.
    self%mark = 0
    self%mark_stamp = 0
    self%n_dense = 0
    if (present(dense_lower) .and. present(dense_upper) .and. present(max_dense)) then
      if (all(ieee_is_finite(dense_lower)) .and. all(ieee_is_finite(dense_upper)) .and. &
          all(dense_upper >= dense_lower) .and. all(abs(dense_lower)*self%inv_h < MAX_BOX_COORD) .and. &
          all(abs(dense_upper)*self%inv_h < MAX_BOX_COORD)) then
        block_lo = floor(dense_lower*self%inv_h, kind=i8)
        block_n = floor(dense_upper*self%inv_h, kind=i8) - block_lo + 1
        ! (the product in reals: three counts up to 2^61 overflow int64)
        if (product(real(block_n, dp)) <= real(max_dense, dp)) then
          self%dense_lo = block_lo
          self%dense_n = block_n
          self%n_dense = int(product(block_n))
        end if
      end if
    end if
    self%table_size = 1024
    n_slots = self%n_dense + self%table_size
    allocate (self%slot_key(3, n_slots), self%slot_used(n_slots), self%list(3, n_slots), self%pool(4*n_slots))
    self%slot_used = .false.
    self%slot_used(1:self%n_dense) = .true.
    self%list(:, 1:self%n_dense) = 0
    self%n_used = 0
    self%pool_top = 0
    self%pool_live = 0
    allocate (self%large_ids(16))
    self%n_large = 0
  end subroutine cells_init

  subroutine cells_free(self)
    class(cell_grid_t), intent(inout) :: self
    if (allocated(self%placed)) deallocate (self%placed, self%large, self%region, self%lo, self%hi, &
                                            self%mark)
    if (allocated(self%slot_key)) deallocate (self%slot_key, self%slot_used)
    if (allocated(self%list)) deallocate (self%list)
    if (allocated(self%pool)) deallocate (self%pool)
    self%pool_top = 0
    self%pool_live = 0
    if (allocated(self%large_ids)) deallocate (self%large_ids)
    if (allocated(self%touched)) deallocate (self%touched)
    if (allocated(self%touched_ids)) deallocate (self%touched_ids)
    if (allocated(self%touched_rows)) deallocate (self%touched_rows)
    self%journaling = .false.
    self%n_touched = 0
    self%n_large = 0
    self%n_used = 0
    self%table_size = 0
    self%n_dense = 0
  end subroutine cells_free

  !> Copies of a grid without its box table (a cross-rank window saves its loop at every
  !> window's start and restores it only when the window is run again): the intrinsic copy
  !> of a grid allocates every box's list (a million-slot table for 13,500 spheres: 80 ms a
  !> copy, most of a 27,000-sphere gas on two ranks), and gfortran's copy of a type holding
  !> one does so even where the grid has a defined assignment. So a holder is copied with
  !> both grids' tables (with their sizes and the journal's list of bodies) swapped out
  !> into holders (swap_table; swapped back after the copy, which then holds none of its
  !> own but what it had before). A grid whose other components are restored from such a
  !> copy keeps its own table: the bodies placed since the copy (start_journal) leave it
  !> before the restore and enter it again at their restored ranges after it
  !> (restore_prepare, restore_finish). What a grid answers depends only on which bodies
  !> each box lists: a query's result is sorted, so neither the order within a box nor the
  !> table's layout shows.
  subroutine cells_swap_table(self, lists)
    class(cell_grid_t), intent(inout) :: self
    type(cell_lists_t), intent(inout) :: lists
    call swap_lists(self%list, lists%list)
    call swap_ints(self%pool, lists%pool)
    call swap_ints(self%touched_ids, lists%touched_ids)
    call swap_ints(self%mark, lists%mark)
    call swap_logicals(self%placed, lists%placed)
    call swap_logicals(self%large, lists%large)
    call swap_logicals(self%touched, lists%touched)
    call swap_reals(self%region, lists%region)
    call swap_keys(self%lo, lists%lo)
    call swap_keys(self%hi, lists%hi)
    call swap_keys(self%touched_rows, lists%touched_rows)
    call swap_int(self%table_size, lists%table_size)
    call swap_int(self%n_used, lists%n_used)
    call swap_int(self%pool_top, lists%pool_top)
    call swap_int(self%pool_live, lists%pool_live)
    call swap_int(self%n_touched, lists%n_touched)
    call swap_keys(self%slot_key, lists%slot_key)
    call swap_logicals(self%slot_used, lists%slot_used)
  contains
    subroutine swap_logicals(a, b)
      logical, allocatable, intent(inout) :: a(:), b(:)
      logical, allocatable :: c(:)
      call move_alloc(b, c)
      call move_alloc(a, b)
      call move_alloc(c, a)
    end subroutine swap_logicals
    subroutine swap_reals(a, b)
      real(dp), allocatable, intent(inout) :: a(:, :), b(:, :)
      real(dp), allocatable :: c(:, :)
      call move_alloc(b, c)
      call move_alloc(a, b)
      call move_alloc(c, a)
    end subroutine swap_reals
    subroutine swap_keys(a, b)
      integer(i8), allocatable, intent(inout) :: a(:, :), b(:, :)
      integer(i8), allocatable :: c(:, :)
      call move_alloc(b, c)
      call move_alloc(a, b)
      call move_alloc(c, a)
    end subroutine swap_keys
    subroutine swap_lists(a, b)
      integer, allocatable, intent(inout) :: a(:, :), b(:, :)
      integer, allocatable :: c(:, :)
      call move_alloc(b, c)
      call move_alloc(a, b)
      call move_alloc(c, a)
    end subroutine swap_lists
    subroutine swap_ints(a, b)
      integer, allocatable, intent(inout) :: a(:), b(:)
      integer, allocatable :: c(:)
      call move_alloc(b, c)
      call move_alloc(a, b)
      call move_alloc(c, a)
    end subroutine swap_ints
    subroutine swap_int(a, b)
      integer, intent(inout) :: a, b
      integer :: c
      c = a
      a = b
      b = c
    end subroutine swap_int
  end subroutine cells_swap_table

  !> From now on the bodies placed or unplaced are noted (the state restore_prepare and
  !> restore_finish return the lists to is this one).
  subroutine cells_start_journal(self)
    class(cell_grid_t), intent(inout) :: self
    integer :: k
    if (.not. allocated(self%placed)) return
    if (allocated(self%touched)) then
      if (size(self%touched) /= size(self%placed)) deallocate (self%touched)
    end if
    if (.not. allocated(self%touched)) then
      allocate (self%touched(size(self%placed)))
      self%touched = .false.
    else
      do k = 1, self%n_touched
        self%touched(self%touched_ids(k)) = .false.
      end do
    end if
    if (.not. allocated(self%touched_ids)) allocate (self%touched_ids(64))
    if (allocated(self%touched_rows)) then
      if (size(self%touched_rows, 2) /= size(self%touched_ids)) deallocate (self%touched_rows)
    end if
    if (.not. allocated(self%touched_rows)) allocate (self%touched_rows(ROW_WORDS, size(self%touched_ids)))
    self%n_touched = 0
    self%journaling = .true.
  end subroutine cells_start_journal

  !> Before a grid's other components are restored from a copy taken at start_journal
  !> (with the tables and per-body rows set aside: swap_table): the bodies placed or
  !> unplaced since leave the lists (at the ranges they have now). A grid not journaling
  !> (never started: no bodies) empties its table instead, and restore_finish lists every
  !> body again at the ranges it has (n_touched = -1 marks it, carried through the copy with
  !> the table); a grid renumbered since the copy (remap_bodies) has no state to go back to.
  subroutine cells_restore_prepare(self)
    class(cell_grid_t), intent(inout) :: self
    integer :: k
    if (.not. self%journaling) then
      if (allocated(self%slot_used)) then
        self%slot_used = .false.
        self%slot_used(1:self%n_dense) = .true.
        self%list(:, 1:self%n_dense) = 0
      end if
      self%n_used = 0
      self%pool_top = 0
      self%pool_live = 0
      self%n_touched = -1
      return
    end if
    do k = 1, self%n_touched
      call self%unplace(self%touched_ids(k))
    end do
  end subroutine cells_restore_prepare

  !> After that restore: the same bodies get back their rows of the copy's time (from the
  !> journal) and enter the lists at those ranges; the lists are then those of the copy's
  !> time, and the journal starts again from there.
  subroutine cells_restore_finish(self)
    class(cell_grid_t), intent(inout) :: self
    integer :: k
    if (self%n_touched < 0) then
      ! (no journal: every body listed again from its restored range)
      do k = 1, size(self%placed)
        call list_again(k)
      end do
      self%n_touched = 0
      return
    end if
    ! (each row as it was at the start: the copy did not carry the rows)
    do k = 1, self%n_touched
      call unpack_row(self%touched_ids(k), self%touched_rows(:, k))
    end do
    do k = 1, self%n_touched
      call list_again(self%touched_ids(k))
    end do
    do k = 1, self%n_touched
      if (self%touched_ids(k) <= size(self%touched)) self%touched(self%touched_ids(k)) = .false.
    end do
    self%n_touched = 0
    ! (the query stamps went back with the copy, the marks did not: none may match one)
    self%mark = 0
    self%mark_stamp = 0
  contains
    subroutine unpack_row(i, words)
      integer, intent(in) :: i
      integer(i8), intent(in) :: words(ROW_WORDS)
      self%placed(i) = words(1) /= 0
      self%large(i) = words(2) /= 0
      self%region(:, i) = transfer(words(3:8), self%region(:, i))
      self%lo(:, i) = words(9:11)
      self%hi(:, i) = words(12:14)
    end subroutine unpack_row
    subroutine list_again(i)
      integer, intent(in) :: i
      integer(i8) :: a, b, c
      if (.not. self%placed(i) .or. self%large(i)) return
      do c = self%lo(3, i), self%hi(3, i)
        do b = self%lo(2, i), self%hi(2, i)
          do a = self%lo(1, i), self%hi(1, i)
            call insert(self, [a, b, c], i)
          end do
        end do
      end do
    end subroutine list_again
  end subroutine cells_restore_finish

  !> No more journal (between cross-rank windows).
  subroutine cells_stop_journal(self)
    class(cell_grid_t), intent(inout) :: self
    integer :: k
    if (self%journaling) then
      do k = 1, self%n_touched
        self%touched(self%touched_ids(k)) = .false.
      end do
    end if
    self%n_touched = 0
    self%journaling = .false.
  end subroutine cells_stop_journal

  !> While journaling: body i is about to be placed or unplaced.
  subroutine note(self, i)
    type(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: i
    integer(i8), allocatable :: grown(:, :)
    integer(i8), parameter :: mold = 0_i8
    if (.not. self%journaling) return
    if (self%touched(i)) return
    self%touched(i) = .true.
    if (self%n_touched == size(self%touched_ids)) call grow_list(self%touched_ids)
    if (size(self%touched_rows, 2) < size(self%touched_ids)) then
      allocate (grown(ROW_WORDS, size(self%touched_ids)))
      grown(:, 1:self%n_touched) = self%touched_rows(:, 1:self%n_touched)
      call move_alloc(grown, self%touched_rows)
    end if
    self%n_touched = self%n_touched + 1
    self%touched_ids(self%n_touched) = i
    associate (words => self%touched_rows(:, self%n_touched))
      words(1) = merge(1_i8, 0_i8, self%placed(i))
      words(2) = merge(1_i8, 0_i8, self%large(i))
      words(3:8) = transfer(self%region(:, i), mold, 6)
      words(9:11) = self%lo(:, i)
      words(12:14) = self%hi(:, i)
    end associate
  end subroutine note

  !> Room for bodies up to n.
  subroutine cells_grow_bodies(self, n)
    class(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: n
    logical, allocatable :: l1(:), l2(:)
    real(dp), allocatable :: r1(:, :)
    integer(i8), allocatable :: k1(:, :), k2(:, :)
    integer, allocatable :: m(:)
    integer :: old
    old = size(self%placed)
    if (old >= n) return
    allocate (l1(n), l2(n), r1(6, n), k1(3, n), k2(3, n), m(n))
    l1 = .false.; l2 = .false.; m = 0
    l1(1:old) = self%placed; l2(1:old) = self%large
    r1(:, 1:old) = self%region
    k1(:, 1:old) = self%lo; k2(:, 1:old) = self%hi
    m(1:old) = self%mark
    call move_alloc(l1, self%placed); call move_alloc(l2, self%large)
    call move_alloc(r1, self%region)
    call move_alloc(k1, self%lo); call move_alloc(k2, self%hi)
    call move_alloc(m, self%mark)
    if (allocated(self%touched)) then
      allocate (l1(n))
      l1 = .false.
      l1(1:old) = self%touched
      call move_alloc(l1, self%touched)
    end if
  end subroutine cells_grow_bodies

  !> The bodies were renumbered (a migration): body i is now new_index(i), 0 if it left, of
  !> n_bodies. Bodies that stayed keep their regions and boxes; those that left are taken
  !> out; the others (arrivals) are not placed (the caller places them). The boxes' lists
  !> are renamed in place, so the cost is that of the boxes held, not of placing again.
  subroutine cells_remap_bodies(self, new_index, n_bodies)
    class(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n_bodies
    logical, allocatable :: placed(:), large(:)
    real(dp), allocatable :: region(:, :)
    integer(i8), allocatable :: lo(:, :), hi(:, :)
    integer :: i, ni, s, k, kept
    ! bodies only appended (every old body keeps its number): the table stands as it is
    if (n_bodies >= size(self%placed) .and. keeps_first(new_index, size(self%placed))) then
      call self%grow_bodies(n_bodies)
      return
    end if
    allocate (placed(n_bodies), large(n_bodies), region(6, n_bodies), lo(3, n_bodies), &
              hi(3, n_bodies))
    placed = .false.
    large = .false.
    region = 0.0_dp
    lo = 0
    hi = 0
    do i = 1, min(size(new_index), size(self%placed))
      ni = new_index(i)
      if (ni == 0) cycle
      placed(ni) = self%placed(i)
      large(ni) = self%large(i)
      region(:, ni) = self%region(:, i)
      lo(:, ni) = self%lo(:, i)
      hi(:, ni) = self%hi(:, i)
    end do
    do s = 1, self%n_dense + self%table_size
      if (.not. self%slot_used(s)) cycle
      kept = 0
      do k = self%list(LIST_AT, s) + 1, self%list(LIST_AT, s) + self%list(LIST_N, s)
        ni = renamed(self%pool(k))
        if (ni == 0) cycle
        self%pool(self%list(LIST_AT, s) + kept + 1) = ni
        kept = kept + 1
      end do
      self%list(LIST_N, s) = kept
    end do
    kept = 0
    do k = 1, self%n_large
      ni = renamed(self%large_ids(k))
      if (ni == 0) cycle
      kept = kept + 1
      self%large_ids(kept) = ni
    end do
    self%n_large = kept
    call move_alloc(placed, self%placed)
    call move_alloc(large, self%large)
    call move_alloc(region, self%region)
    call move_alloc(lo, self%lo)
    call move_alloc(hi, self%hi)
    deallocate (self%mark)
    allocate (self%mark(n_bodies))
    self%mark = 0
    self%mark_stamp = 0
    ! (a journal's body numbers mean nothing after a renumbering)
    self%journaling = .false.
    self%n_touched = 0
    if (allocated(self%touched)) deallocate (self%touched)
  contains
    integer function renamed(id)
      integer, intent(in) :: id
      renamed = 0
      if (id >= 1 .and. id <= size(new_index)) renamed = new_index(id)
    end function renamed
  end subroutine cells_remap_bodies

  !> Places body i with the region [lower, upper] [m] (moving it if placed before).
  subroutine cells_place(self, i, lower, upper, err)
    class(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: i
    real(dp), intent(in) :: lower(3), upper(3)
    type(error_t), intent(inout) :: err
    integer(i8) :: a, b, c
    call note(self, i)
    if (self%placed(i)) call self%unplace(i)
    if (.not. (all(ieee_is_finite(lower)) .and. all(ieee_is_finite(upper)))) then
      call err%set(ERR_NUMERIC, 'cell grid: a body''s region is not finite (a position became NaN or Inf)')
      return
    end if
    if (any(abs(lower)*self%inv_h > MAX_BOX_COORD) .or. any(abs(upper)*self%inv_h > MAX_BOX_COORD)) then
      call err%set(ERR_NUMERIC, 'cell grid: a body is more than 2^60 boxes from the origin')
      return
    end if
    self%region(1:3, i) = lower
    self%region(4:6, i) = upper
    ! floor(..., kind=i8), not int(floor(...), i8): the default-kind floor overflows past
    ! 2^31 boxes (a 1e4 m body in 2e-6 m boxes), giving hi < lo, and the body would be
    ! listed nowhere (neither in boxes nor as large) and tunnelled through.
    self%lo(:, i) = floor(lower*self%inv_h, kind=i8)
    self%hi(:, i) = floor(upper*self%inv_h, kind=i8)
    self%placed(i) = .true.
    self%placements = self%placements + 1
    if (any(self%hi(:, i) - self%lo(:, i) + 1 > self%max_span)) then
      self%large(i) = .true.
      if (self%n_large == size(self%large_ids)) call grow_list(self%large_ids)
      self%n_large = self%n_large + 1
      self%large_ids(self%n_large) = i
      return
    end if
    self%large(i) = .false.
    do c = self%lo(3, i), self%hi(3, i)
      do b = self%lo(2, i), self%hi(2, i)
        do a = self%lo(1, i), self%hi(1, i)
          call insert(self, [a, b, c], i)
        end do
      end do
    end do
  end subroutine cells_place

  subroutine cells_unplace(self, i)
    class(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: i
    integer(i8) :: a, b, c
    integer :: k
    if (.not. self%placed(i)) return
    call note(self, i)
    self%placed(i) = .false.
    if (self%large(i)) then
      do k = 1, self%n_large
        if (self%large_ids(k) == i) then
          self%large_ids(k:self%n_large - 1) = self%large_ids(k + 1:self%n_large)
          self%n_large = self%n_large - 1
          exit
        end if
      end do
      self%large(i) = .false.
      return
    end if
    do c = self%lo(3, i), self%hi(3, i)
      do b = self%lo(2, i), self%hi(2, i)
        do a = self%lo(1, i), self%hi(1, i)
          call delete(self, [a, b, c], i)
        end do
      end do
    end do
  end subroutine cells_unplace

  !> Do the regions of bodies i and j overlap?
  pure logical function cells_overlaps(self, i, j)
    class(cell_grid_t), intent(in) :: self
    integer, intent(in) :: i, j
    cells_overlaps = all(self%region(1:3, i) <= self%region(4:6, j)) .and. &
                     all(self%region(1:3, j) <= self%region(4:6, i))
  end function cells_overlaps

  !> The placed bodies whose regions overlap body i's (i placed), into found(1:n_found), in
  !> increasing index. n_bodies: bodies to scan when i itself is large (its region is not
  !> in the boxes: every placed body is tested).
  subroutine cells_query(self, i, found, n_found, n_bodies)
    class(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: i
    integer, allocatable, intent(inout) :: found(:)
    integer, intent(out) :: n_found
    integer, intent(in) :: n_bodies
    integer(i8) :: a, b, c
    integer :: s, k, j
    n_found = 0
    if (.not. allocated(found)) allocate (found(64))
    call next_stamp(self)
    self%mark(i) = self%mark_stamp
    if (self%large(i)) then
      do j = 1, n_bodies
        if (j == i .or. .not. self%placed(j)) cycle
        if (self%overlaps(i, j)) call push(j)
      end do
    else
      do c = self%lo(3, i), self%hi(3, i)
        do b = self%lo(2, i), self%hi(2, i)
          do a = self%lo(1, i), self%hi(1, i)
            s = find_slot(self, [a, b, c])
            if (s == 0) cycle
            do k = self%list(LIST_AT, s) + 1, self%list(LIST_AT, s) + self%list(LIST_N, s)
              j = self%pool(k)
              if (self%mark(j) == self%mark_stamp) cycle
              self%mark(j) = self%mark_stamp
              if (self%overlaps(i, j)) call push(j)
            end do
          end do
        end do
      end do
      do k = 1, self%n_large
        j = self%large_ids(k)
        if (j /= i .and. self%overlaps(i, j)) call push(j)
      end do
    end if
    call sort_ints(found(1:n_found))
  contains
    subroutine push(jj)
      integer, intent(in) :: jj
      if (n_found == size(found)) call grow_list(found)
      n_found = n_found + 1
      found(n_found) = jj
    end subroutine push
  end subroutine cells_query

  subroutine next_stamp(self)
    type(cell_grid_t), intent(inout) :: self
    if (self%mark_stamp == huge(self%mark_stamp)) then
      self%mark = 0
      self%mark_stamp = 0
    end if
    self%mark_stamp = self%mark_stamp + 1
  end subroutine next_stamp

  pure integer function hash_of(key, table_size) result(s)
    integer(i8), intent(in) :: key(3)
    integer, intent(in) :: table_size
    integer(i8) :: h
    ! large odd multipliers, then the low bits (table sizes are powers of two); the low 30
    ! bits of each coordinate only, so that the products cannot overflow int64 for
    ! coordinates up to MAX_BOX_COORD (keys are compared in full: this only spreads them)
    h = iand(key(1), KEY_MASK)*73856093_i8 + iand(key(2), KEY_MASK)*19349669_i8 + &
        iand(key(3), KEY_MASK)*83492791_i8
    h = ieor(h, ishft(h, -17))
    s = int(iand(h, int(table_size - 1, i8))) + 1
  end function hash_of

  !> The slot holding box key, 0 if none (a box of the dense block always has one).
  pure integer function find_slot(self, key) result(s)
    type(cell_grid_t), intent(in) :: self
    integer(i8), intent(in) :: key(3)
    integer(i8) :: d(3)
    integer :: probes
    if (self%n_dense > 0) then
      d = key - self%dense_lo
      if (all(d >= 0_i8 .and. d < self%dense_n)) then
        s = 1 + int(d(1) + self%dense_n(1)*(d(2) + self%dense_n(2)*d(3)))
        return
      end if
    end if
    s = self%n_dense + hash_of(key, self%table_size)
    do probes = 1, self%table_size
      if (.not. self%slot_used(s)) then
        s = 0
        return
      end if
      if (all(self%slot_key(:, s) == key)) return
      s = s + 1
      if (s > self%n_dense + self%table_size) s = self%n_dense + 1
    end do
    s = 0
  end function find_slot

  subroutine insert(self, key, i)
    type(cell_grid_t), intent(inout) :: self
    integer(i8), intent(in) :: key(3)
    integer, intent(in) :: i
    integer :: s
    s = find_slot(self, key)
    if (s == 0) then
      ! (linear probing up to 60% full: 1.75 probes a hit, 3.6 a miss; at 50% the 6,000
      ! ghosts of a 100,000-sphere gas's first window on two ranks tipped a table just
      ! filled to half by the owned bodies into a rehash to twice its size, 78 MB of fresh
      ! pages)
      if (5*(int(self%n_used, i8) + 1) > 3*int(self%table_size, i8)) call rehash(self)
      s = self%n_dense + hash_of(key, self%table_size)
      do while (self%slot_used(s))
        s = s + 1
        if (s > self%n_dense + self%table_size) s = self%n_dense + 1
      end do
      self%slot_used(s) = .true.
      self%slot_key(:, s) = key
      self%list(:, s) = 0
      self%n_used = self%n_used + 1
    end if
    if (self%list(LIST_N, s) == self%list(LIST_CAP, s)) &
      call give_room(self, s, max(first_room, 2*self%list(LIST_CAP, s)))
    self%list(LIST_N, s) = self%list(LIST_N, s) + 1
    self%pool(self%list(LIST_AT, s) + self%list(LIST_N, s)) = i
  end subroutine insert

  !> Box slot s's list moves to a room of cap entries at the pool's top (its ids kept).
  subroutine give_room(self, s, cap)
    type(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: s, cap
    integer :: at, from, n
    if (self%pool_top + cap > size(self%pool)) call make_room(self, cap)
    at = self%pool_top
    from = self%list(LIST_AT, s)
    n = self%list(LIST_N, s)
    self%pool(at + 1:at + n) = self%pool(from + 1:from + n)
    self%pool_live = self%pool_live - self%list(LIST_CAP, s) + cap
    self%pool_top = at + cap
    self%list(LIST_AT, s) = at
    self%list(LIST_CAP, s) = cap
  end subroutine give_room

  !> Room for cap more entries at the pool's top: the pool compacted (every list of the
  !> table packed in slot order, with its room) when at least half of it is unused rooms,
  !> else grown to twice its size.
  subroutine make_room(self, cap)
    type(cell_grid_t), intent(inout) :: self
    integer, intent(in) :: cap
    integer, allocatable :: packed(:)
    integer :: s, at, new_size, from, n
    integer(i8) :: wanted
    ! (in 64 bits: twice the rooms passes 2^31 entries long before the pool's indices do)
    wanted = min(2_i8*(int(self%pool_live, i8) + cap), int(huge(0), i8))
    new_size = size(self%pool)
    do while (new_size < wanted)
      new_size = int(min(2_i8*new_size, int(huge(0), i8)))
    end do
    if (2*self%pool_live <= self%pool_top) then
      allocate (packed(new_size))
      at = 0
      do s = 1, self%n_dense + self%table_size
        if (.not. self%slot_used(s)) cycle
        from = self%list(LIST_AT, s)
        n = self%list(LIST_N, s)
        packed(at + 1:at + n) = self%pool(from + 1:from + n)
        self%list(LIST_AT, s) = at
        at = at + self%list(LIST_CAP, s)
      end do
      self%pool_top = at
      call move_alloc(packed, self%pool)
    else
      allocate (packed(new_size))
      packed(1:self%pool_top) = self%pool(1:self%pool_top)
      call move_alloc(packed, self%pool)
    end if
  end subroutine make_room

  subroutine delete(self, key, i)
    type(cell_grid_t), intent(inout) :: self
    integer(i8), intent(in) :: key(3)
    integer, intent(in) :: i
    integer :: s, k
    s = find_slot(self, key)
    if (s == 0) return
    do k = self%list(LIST_AT, s) + 1, self%list(LIST_AT, s) + self%list(LIST_N, s)
      if (self%pool(k) == i) then
        self%pool(k) = self%pool(self%list(LIST_AT, s) + self%list(LIST_N, s))
        self%list(LIST_N, s) = self%list(LIST_N, s) - 1
        return
      end if
    end do
  end subroutine delete

  !> A table at least three times the boxes still holding bodies (empty boxes are dropped,
  !> so a body flying far does not leave a trail of boxes behind; their rooms in the pool
  !> are given up). At the size it has (most rehashes: bodies moving on leave empty boxes
  !> behind) it is emptied and filled again in place: a fresh table of millions of slots
  !> (100,000 spheres on two ranks) costs its page faults every time. Only the slots move:
  !> the lists stay where they are in the pool.
  subroutine rehash(self)
    type(cell_grid_t), intent(inout) :: self
    integer(i8), allocatable :: old_key(:, :)
    integer, allocatable :: old_n(:), old_at(:), old_cap(:), keep(:, :)
    integer :: s, t, m, occupied, new_size, nd
    ! (the dense block's slots, 1..nd, stay as they are)
    nd = self%n_dense
    occupied = 0
    do s = nd + 1, nd + self%table_size
      if (self%slot_used(s)) then
        if (self%list(LIST_N, s) > 0) occupied = occupied + 1
      end if
    end do
    ! (at least 3 slots per occupied box: a third full at most after the rehash, 60% at the
    ! next; 4 made a 100,000-sphere rank's table 4M slots, 160 MB of fresh pages, where 2M do)
    new_size = self%table_size
    do while (new_size < 3*(occupied + 1))
      new_size = 2*new_size
    end do
    ! the boxes holding bodies set aside (their lists stay where they are in the pool), the
    ! empty ones' rooms given up
    allocate (old_key(3, occupied), old_n(occupied), old_at(occupied), old_cap(occupied))
    m = 0
    do s = nd + 1, nd + self%table_size
      if (.not. self%slot_used(s)) cycle
      if (self%list(LIST_N, s) == 0) then
        self%pool_live = self%pool_live - self%list(LIST_CAP, s)
        cycle
      end if
      m = m + 1
      old_key(:, m) = self%slot_key(:, s)
      old_n(m) = self%list(LIST_N, s)
      old_at(m) = self%list(LIST_AT, s)
      old_cap(m) = self%list(LIST_CAP, s)
    end do
    if (new_size /= self%table_size) then
      keep = self%list(:, 1:nd)
      deallocate (self%slot_key, self%slot_used, self%list)
      allocate (self%slot_key(3, nd + new_size), self%slot_used(nd + new_size), self%list(3, nd + new_size))
      self%slot_used(1:nd) = .true.
      self%list(:, 1:nd) = keep
      self%table_size = new_size
    end if
    self%slot_used(nd + 1:) = .false.
    self%n_used = 0
    do m = 1, occupied
      t = nd + hash_of(old_key(:, m), self%table_size)
      do while (self%slot_used(t))
        t = t + 1
        if (t > nd + self%table_size) t = nd + 1
      end do
      self%slot_used(t) = .true.
      self%slot_key(:, t) = old_key(:, m)
      self%list(LIST_N, t) = old_n(m)
      self%list(LIST_AT, t) = old_at(m)
      self%list(LIST_CAP, t) = old_cap(m)
      self%n_used = self%n_used + 1
    end do
  end subroutine rehash

  subroutine grow_list(x)
    integer, allocatable, intent(inout) :: x(:)
    integer, allocatable :: y(:)
    allocate (y(2*size(x)))
    y(1:size(x)) = x
    call move_alloc(y, x)
  end subroutine grow_list

  !> Insertion sort: query results are short.
  pure subroutine sort_ints(x)
    integer, intent(inout) :: x(:)
    integer :: k, m, v
    do k = 2, size(x)
      v = x(k)
      m = k - 1
      do while (m >= 1)
        if (x(m) <= v) exit
        x(m + 1) = x(m)
        m = m - 1
      end do
      x(m + 1) = v
    end do
  end subroutine sort_ints

end module cell_grid
