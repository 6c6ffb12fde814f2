!> Broad phase, the "bucket sort": a uniform grid of cubic boxes of edge h whose size follows
!> the smallest dynamic body, so that any body listed in it touches at most a few boxes per
!> axis and "no body moves more than one box per step" is a meaningful step limit.
!>
!> Boxes are indexed globally: box (i,j,k) = floor((x - origin)/h) per axis, as 64-bit
!> integers, from one origin and one h shared by all ranks, so a subdomain is a range of boxes.
!> Each grid body is listed in every box its bounding box touches; the (box, body) entries are
!> counting-sorted by slot into one flat array (no per-box allocatable lists). Slots: an
!> open-addressing hash table of >= 2 slots per entry (the domain is unbounded), or, when the
!> occupied boxes fill their bounding box, a dense array of those boxes (neighbours adjacent in
!> memory). Build is O(n), a query O(n + pairs).
!>
!> Bodies whose bounding box spans more than max_span boxes along some axis (floors, walls,
!> containers, or dynamic bodies much larger than the smallest) are not put in the grid, so
!> they neither shrink the boxes nor flood thousands of them: they go into a flat bounding
!> volume hierarchy (arrays, median split) that each grid body queries with its inflated box.
!> A container of 10,000 small bodies then costs 10,000 grid bodies plus a few box tests each
!> against the walls. Small static bodies (pegs, obstacles) stay in the grid; static-static
!> pairs are never reported.
!>
!> Candidate pairs: unordered (i<j), unique, sorted by (i, j), of bodies whose boxes lie within
!> `rings` boxes of each other and whose bounding boxes, each inflated by its own margin,
!> overlap. Bodies far from everything produce no pair and so cost no mesh query.
!> Design, rules for callers and measurements: docs/broad_phase.md.
module bucket_grid
  use kinds, only: dp, i8
  use, intrinsic :: iso_fortran_env, only: int8
  use error_status, only: error_t, ERR_INPUT
  use sorting, only: select_kth
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  implicit none
  private
  public :: bucket_grid_t, bucket_stats_t, choose_box_size
  public :: BUCKET_DEFAULT_MAX_SPAN

  !> A body spanning more boxes than this along some axis is "large" (kept out of the grid):
  !> with h = extent of the smallest dynamic body, bodies up to about 3 h stay in the grid
  !> (at most 4^3 = 64 entries each), anything bigger goes to the hierarchy.
  integer, parameter :: BUCKET_DEFAULT_MAX_SPAN = 4
  integer, parameter :: LEAF_SIZE = 4          !< bodies per hierarchy leaf
  integer, parameter :: STACK_SIZE = 128       !< median split: depth <= log2(n)+1 < 64
  !> |box coordinate| limit: keeps floor() and +-rings far from int64 overflow.
  real(dp), parameter :: MAX_BOX_COORD = 2.0_dp**60
  integer(i8), parameter :: LOW21 = 2_i8**21 - 1
  integer(i8), parameter :: LOW31 = 2_i8**31 - 1

  !> What the last build and query did (for logs, tests and benchmarks).
  type :: bucket_stats_t
    integer :: n_bodies = 0       !< bodies given to build (owned + ghosts)
    integer :: n_grid = 0         !< of them listed in the grid
    integer :: n_large = 0        !< of them in the large-body hierarchy (static or oversized)
    integer :: n_entries = 0      !< (box, body) entries in the grid
    integer :: cells_used = 0     !< occupied boxes
    integer :: max_per_cell = 0   !< most bodies listed in one box
    integer :: table_size = 0     !< slots: hash (power of two, >= 2 n_entries) or dense boxes
    integer(i8) :: pairs_tested = 0    !< inflated bounding-box comparisons in the last query
    integer(i8) :: pairs_returned = 0  !< pairs returned by the last query
    logical :: dense = .false.    !< dense slot array instead of the hash
  end type bucket_stats_t

  type :: bucket_grid_t
    private
    real(dp) :: h = 0.0_dp          !< box edge [m]
    real(dp) :: inv_h = 0.0_dp      !< 1/h [1/m]
    real(dp) :: origin(3) = 0.0_dp  !< corner of box (0,0,0) [m]
    real(dp) :: max_reach = 0.0_dp  !< MAX_BOX_COORD boxes [m]: farthest a box may be from origin
    integer :: max_span = BUCKET_DEFAULT_MAX_SPAN
    logical :: initialised = .false.
    logical :: built = .false.
    integer :: n = 0
    real(dp), allocatable :: lower(:, :), upper(:, :)   !< (3,n) world bounding boxes [m]
    logical, allocatable :: is_static(:), in_grid(:)
    integer(i8), allocatable :: lo(:, :), hi(:, :)      !< (3,n) box range of each body
    ! Slot s holds box slot_key(:,s) with slot_count(s) > 0 bodies in
    ! cell_body(slot_start(s) : slot_start(s)+slot_count(s)-1), given by rank in `order`.
    ! Hash mode: open addressing, linear probing. Dense mode (the occupied boxes fill their
    ! bounding box kmin..kmax well, as in a gas or a full container): slot = 1 + the box's
    ! lexicographic index in that bounding box, no key, and neighbouring boxes are
    ! neighbouring slots (cache-friendly queries).
    integer :: table_size = 0
    logical :: dense = .false.
    integer(i8) :: kmin(3) = 0, kmax(3) = -1, dim1 = 0, dim12 = 0
    integer, allocatable :: order(:)   !< grid bodies in the order queries visit them (rank -> body)
    ! Copies of the grid bodies' boxes by rank: in dense mode ranks follow space, so a query's
    ! neighbours are close in memory whatever the caller's body order (no random access).
    real(dp), allocatable :: r_lower(:, :), r_upper(:, :), r_margin(:)
    integer(i8), allocatable :: r_lo(:, :), r_hi(:, :)
    logical, allocatable :: r_static(:)
    integer(i8), allocatable :: slot_key(:, :)
    integer, allocatable :: slot_count(:), slot_start(:), slot_fill(:)
    integer, allocatable :: cell_body(:), entry_slot(:)
    ! Per entry, beside cell_body: bit a-1 set if the entry's box is body's first box along
    ! axis a, bit 3 if the body is static. Queries read these contiguous bits instead of the
    ! body arrays at random indices, so most rejected neighbours cost no cache miss.
    integer(int8), allocatable :: cell_flags(:)
    ! Large bodies: a flat hierarchy over large_ids. Node k is a leaf if node_count(k) > 0
    ! (bodies large_ids(node_first(k) : +node_count(k)-1)), else its children are
    ! node_first(k) and node_first(k)+1.
    integer :: n_large = 0, n_large_dynamic = 0, n_nodes = 0
    integer, allocatable :: large_ids(:)
    real(dp), allocatable :: node_lower(:, :), node_upper(:, :)
    integer, allocatable :: node_first(:), node_count(:)
    ! Pair buffers reused between queries (grown, never shrunk).
    integer, allocatable :: pair_buf(:, :), pair_tmp(:, :), counts(:)
    type(bucket_stats_t) :: last
  contains
    procedure :: init => grid_init
    procedure :: free => grid_free
    procedure :: build => grid_build
    procedure :: candidate_pairs => grid_candidate_pairs
    procedure :: max_step_displacement => grid_max_step_displacement
    procedure :: box_size => grid_box_size
    procedure :: box_of_point => grid_box_of_point
    procedure :: stats => grid_stats
  end type bucket_grid_t

contains

  !> Box size from the dynamic bodies: h = scale * min_i extent_i, where extent_i is body
  !> i's largest bounding-box side, best its rotation-invariant 2 x bounding radius about the
  !> centre of mass (so h does not change as bodies tumble). Why the smallest body: it must be
  !> the one that cannot tunnel, so one box per step must be at most about its own size, and
  !> boxes no bigger than a few small bodies keep box occupancy bounded in dense packings.
  !> With scale >= 1 the smallest body touches at most 2 boxes per axis; bodies up to
  !> (max_span-1) h stay in the grid, bigger ones go to the large-body hierarchy.
  !> scale (the deck option) must be >= 1: smaller boxes only add entries and shorten steps.
  subroutine choose_box_size(extent, scale, box_size, err)
    real(dp), intent(in) :: extent(:)   !< [m] largest extent of each dynamic body
    real(dp), intent(in) :: scale       !< [-] box size / smallest extent, >= 1
    real(dp), intent(out) :: box_size   !< [m]
    type(error_t), intent(inout) :: err
    character(len=32) :: buf
    box_size = 0.0_dp
    if (size(extent) == 0) then
      call err%set(ERR_INPUT, 'bucket grid: no dynamic body to size the grid boxes from')
      return
    end if
    if (.not. ieee_is_finite(scale) .or. scale < 1.0_dp) then
      write (buf, '(es12.4)') scale
      call err%set(ERR_INPUT, 'bucket grid: box size scale = '//trim(adjustl(buf))// &
                   ' must be finite and >= 1 (boxes smaller than the smallest body)')
      return
    end if
    if (.not. all(extent > 0.0_dp .and. extent <= huge(1.0_dp))) then
      write (buf, '(i0)') findloc(extent > 0.0_dp .and. extent <= huge(1.0_dp), .false., dim=1)
      call err%set(ERR_INPUT, 'bucket grid: extent of dynamic body '//trim(buf)// &
                   ' is not a finite positive length')
      return
    end if
    box_size = scale*minval(extent)
  end subroutine choose_box_size

  !> Sets the box size h [m] (and optionally the global origin [m] of box (0,0,0) and the
  !> span above which a body counts as large). Every rank must use the same h and origin.
  subroutine grid_init(self, box_size, err, origin, max_span)
    class(bucket_grid_t), intent(inout) :: self
    real(dp), intent(in) :: box_size
    type(error_t), intent(inout) :: err
    real(dp), intent(in), optional :: origin(3)
    integer, intent(in), optional :: max_span
    character(len=32) :: buf
    call self%free()
    if (.not. ieee_is_finite(box_size) .or. box_size <= 0.0_dp) then
      write (buf, '(es12.4)') box_size
      call err%set(ERR_INPUT, 'bucket grid: box size = '//trim(adjustl(buf))//' m must be finite and > 0')
      return
    end if
    self%h = box_size
    self%inv_h = 1.0_dp/box_size
    self%max_reach = huge(1.0_dp)
    if (box_size < huge(1.0_dp)/MAX_BOX_COORD) self%max_reach = MAX_BOX_COORD*box_size
    if (present(origin)) then
      if (.not. all(ieee_is_finite(origin))) then
        call err%set(ERR_INPUT, 'bucket grid: origin is not finite')
        return
      end if
      self%origin = origin
    end if
    if (present(max_span)) then
      if (max_span < 1) then
        write (buf, '(i0)') max_span
        call err%set(ERR_INPUT, 'bucket grid: max_span = '//trim(buf)//' must be >= 1')
        return
      end if
      self%max_span = max_span
    end if
    self%initialised = .true.
  end subroutine grid_init

  subroutine grid_free(self)
    class(bucket_grid_t), intent(inout) :: self
    self%h = 0.0_dp
    self%inv_h = 0.0_dp
    self%origin = 0.0_dp
    self%max_span = BUCKET_DEFAULT_MAX_SPAN
    self%initialised = .false.
    self%built = .false.
    self%n = 0
    self%table_size = 0
    self%dense = .false.
    self%n_large = 0
    self%n_large_dynamic = 0
    self%n_nodes = 0
    if (allocated(self%lower)) deallocate (self%lower, self%upper, self%is_static, self%in_grid, self%lo, self%hi)
    if (allocated(self%slot_key)) deallocate (self%slot_key)
    if (allocated(self%slot_count)) deallocate (self%slot_count, self%slot_start, self%slot_fill)
    if (allocated(self%cell_body)) deallocate (self%cell_body, self%entry_slot, self%cell_flags)
    if (allocated(self%large_ids)) deallocate (self%large_ids)
    if (allocated(self%order)) deallocate (self%order, self%r_lower, self%r_upper, self%r_margin, &
                                          self%r_lo, self%r_hi, self%r_static)
    if (allocated(self%node_lower)) deallocate (self%node_lower, self%node_upper, self%node_first, self%node_count)
    if (allocated(self%pair_buf)) deallocate (self%pair_buf)
    if (allocated(self%pair_tmp)) deallocate (self%pair_tmp)
    if (allocated(self%counts)) deallocate (self%counts)
    self%last = bucket_stats_t()
  end subroutine grid_free

  !> The bound a caller uses to cap the step: no body may move more than this [m] per step.
  pure real(dp) function grid_max_step_displacement(self) result(d)
    class(bucket_grid_t), intent(in) :: self
    d = self%h
  end function grid_max_step_displacement

  pure real(dp) function grid_box_size(self) result(d)
    class(bucket_grid_t), intent(in) :: self
    d = self%h
  end function grid_box_size

  !> Global integer box coordinates of a point [m] (for domain decomposition).
  pure function grid_box_of_point(self, x) result(c)
    class(bucket_grid_t), intent(in) :: self
    real(dp), intent(in) :: x(3)
    integer(i8) :: c(3)
    c = floor((x - self%origin)*self%inv_h, kind=i8)
  end function grid_box_of_point

  pure type(bucket_stats_t) function grid_stats(self) result(s)
    class(bucket_grid_t), intent(in) :: self
    s = self%last
  end function grid_stats

  !> First probe slot (1-based) of box c in a table of mask+1 slots. Boxes of one row (same
  !> j, k; consecutive i) get consecutive slots, so a query's window row is one or two cache
  !> lines whether its boxes are occupied or not; rows are scattered by a mix of (j, k). Only
  !> the low 21 bits of j and k enter the mix (no integer overflow: the sum stays below 2^50,
  !> the product below 2^62); boxes whose rows alias collide in the hash but keys are compared
  !> whole.
  pure integer function hash_slot(c, mask) result(s)
    integer(i8), intent(in) :: c(3)
    integer(i8), intent(in) :: mask
    integer(i8) :: k
    k = iand(c(2), LOW21)*73856093_i8 + iand(c(3), LOW21)*83492791_i8
    k = ieor(k, ishft(k, -23))
    k = iand(k, LOW31)*1597334677_i8
    k = ieor(k, ishft(k, -29))
    s = int(iand(iand(k, mask) + iand(c(1), mask), mask)) + 1
  end function hash_slot

  !> Dense mode: slot of box c inside kmin..kmax.
  pure integer function dense_slot(self, c) result(s)
    class(bucket_grid_t), intent(in) :: self
    integer(i8), intent(in) :: c(3)
    s = int((c(1) - self%kmin(1)) + self%dim1*(c(2) - self%kmin(2)) + self%dim12*(c(3) - self%kmin(3))) + 1
  end function dense_slot

  !> Slot holding box c, or 0 if no body is listed in it.
  pure integer function find_slot(self, c) result(s)
    class(bucket_grid_t), intent(in) :: self
    integer(i8), intent(in) :: c(3)
    integer(i8) :: mask
    if (self%dense) then
      s = 0
      if (any(c < self%kmin .or. c > self%kmax)) return
      s = dense_slot(self, c)
      if (self%slot_count(s) == 0) s = 0
      return
    end if
    mask = int(self%table_size - 1, i8)
    s = hash_slot(c, mask)
    do
      if (self%slot_count(s) == 0) then
        s = 0
        return
      end if
      if (self%slot_key(1, s) == c(1) .and. self%slot_key(2, s) == c(2) .and. self%slot_key(3, s) == c(3)) return
      s = iand(s, self%table_size - 1) + 1
    end do
  end function find_slot

  !> Lists n bodies (owned then ghosts) by their world bounding boxes lower(3,n)..upper(3,n)
  !> [m]. is_static marks bodies that never move (no static-static pair is ever reported).
  subroutine grid_build(self, n, lower, upper, is_static, err)
    class(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: n
    real(dp), intent(in) :: lower(:, :), upper(:, :)
    logical, intent(in) :: is_static(:)
    type(error_t), intent(inout) :: err
    integer :: i, s, e, k, r, n_entries, n_grid, nl, tsize, cells, maxc
    integer(int8) :: flags
    integer(i8) :: c(3), mask, span(3), k1, k2, k3
    real(dp) :: ql(3), qu(3)
    character(len=64) :: buf

    self%built = .false.
    if (.not. self%initialised) then
      call err%set(ERR_INPUT, 'bucket grid: build called before init')
      return
    end if
    if (n < 0 .or. size(lower, 1) /= 3 .or. size(upper, 1) /= 3 .or. size(lower, 2) < n .or. &
        size(upper, 2) < n .or. size(is_static) < n) then
      write (buf, '(a,i0)') 'n = ', n
      call err%set(ERR_INPUT, 'bucket grid: build with '//trim(buf)// &
                   ' needs lower(3,n), upper(3,n) and is_static(n)')
      return
    end if
    call ensure_body_arrays(self, n)
    self%n = n
    ! Box ranges; reject boxes that are not boxes or too far out for 64-bit box coordinates.
    do i = 1, n
      if (.not. all(lower(:, i) <= upper(:, i))) then
        write (buf, '(i0)') i
        call err%set(ERR_INPUT, 'bucket grid: bounding box of body '//trim(buf)// &
                     ' has lower > upper or is not finite')
        return
      end if
      ! compared in metres first, so a huge coordinate fails here instead of overflowing
      if (.not. all(abs(lower(:, i) - self%origin) < self%max_reach .and. &
                    abs(upper(:, i) - self%origin) < self%max_reach)) then
        write (buf, '(i0)') i
        call err%set(ERR_INPUT, 'bucket grid: body '//trim(buf)// &
                     ' is more than 2^60 boxes from the grid origin (not finite or far too far)')
        return
      end if
      ql = (lower(:, i) - self%origin)*self%inv_h
      qu = (upper(:, i) - self%origin)*self%inv_h
      self%lower(:, i) = lower(:, i)
      self%upper(:, i) = upper(:, i)
      self%is_static(i) = is_static(i)
      self%lo(:, i) = floor(ql, kind=i8)
      self%hi(:, i) = floor(qu, kind=i8)
    end do

    ! Which bodies go to the grid, and how many (box, body) entries they make.
    n_entries = 0
    n_grid = 0
    nl = 0
    do i = 1, n
      span = self%hi(:, i) - self%lo(:, i) + 1
      self%in_grid(i) = all(span <= self%max_span)
      if (self%in_grid(i)) then
        n_grid = n_grid + 1
        n_entries = n_entries + int(span(1)*span(2)*span(3))
      else
        nl = nl + 1
      end if
    end do

    ! Bounding box of the occupied boxes. Dense slots if they take no more memory than the hash
    ! table would (12 bytes per box against 36 per hash slot, with its 3 x 64-bit key); else a
    ! hash table of at least 2 n_entries slots (load <= 1/2: short probe chains).
    self%kmin = huge(1_i8)
    self%kmax = -huge(1_i8)
    do i = 1, n
      if (.not. self%in_grid(i)) cycle
      self%kmin = min(self%kmin, self%lo(:, i))
      self%kmax = max(self%kmax, self%hi(:, i))
    end do
    tsize = 16
    do while (tsize < 2*n_entries)
      tsize = 2*tsize
    end do
    self%dense = .false.
    if (n_grid > 0) then
      self%dense = product(real(self%kmax - self%kmin + 1, dp)) <= 3.0_dp*real(tsize, dp)
    end if
    if (self%dense) then
      self%dim1 = self%kmax(1) - self%kmin(1) + 1
      self%dim12 = self%dim1*(self%kmax(2) - self%kmin(2) + 1)
      tsize = int(self%dim12*(self%kmax(3) - self%kmin(3) + 1))
    end if
    call ensure_table(self, tsize, n_entries)
    self%table_size = tsize
    ! Grid bodies in space order (by first box): inserting and querying in this order touches
    ! the slots and the copied boxes of one neighbourhood after another (cache), whatever the
    ! caller's body order. The rank of a body is its position in `order`.
    if (allocated(self%order)) then
      if (size(self%order) < n_grid) deallocate (self%order, self%r_lower, self%r_upper, self%r_margin, &
                                                 self%r_lo, self%r_hi, self%r_static)
    end if
    if (.not. allocated(self%order)) then
      k = max(1, n_grid)
      allocate (self%order(k), self%r_lower(3, k), self%r_upper(3, k), self%r_margin(k), &
                self%r_lo(3, k), self%r_hi(3, k), self%r_static(k))
    end if
    e = 0
    do i = 1, n
      if (.not. self%in_grid(i)) cycle
      e = e + 1
      self%order(e) = i
    end do
    call sort_order_spatially(self, n_grid)
    ! Copies of the boxes by rank (the one gather in caller order); the passes below read them.
    do k = 1, n_grid
      i = self%order(k)
      self%r_lower(:, k) = self%lower(:, i)
      self%r_upper(:, k) = self%upper(:, i)
      self%r_lo(:, k) = self%lo(:, i)
      self%r_hi(:, k) = self%hi(:, i)
      self%r_static(k) = self%is_static(i)
    end do
    mask = int(tsize - 1, i8)
    self%slot_count(1:tsize) = 0
    ! Pass 1: find or claim each entry's slot, count bodies per slot.
    e = 0
    do r = 1, n_grid
      do k3 = self%r_lo(3, r), self%r_hi(3, r)
        do k2 = self%r_lo(2, r), self%r_hi(2, r)
          do k1 = self%r_lo(1, r), self%r_hi(1, r)
            c = [k1, k2, k3]
            if (self%dense) then
              s = dense_slot(self, c)
            else
              s = hash_slot(c, mask)
              do
                if (self%slot_count(s) == 0) then
                  self%slot_key(:, s) = c
                  exit
                end if
                if (all(self%slot_key(:, s) == c)) exit
                s = int(iand(int(s, i8), mask)) + 1
              end do
            end if
            self%slot_count(s) = self%slot_count(s) + 1
            e = e + 1
            self%entry_slot(e) = s
          end do
        end do
      end do
    end do
    ! Prefix sum: slot_start; then pass 2 scatters ranks into their slots (counting sort).
    cells = 0
    maxc = 0
    e = 1
    do s = 1, tsize
      self%slot_start(s) = e
      self%slot_fill(s) = e
      e = e + self%slot_count(s)
      if (self%slot_count(s) > 0) cells = cells + 1
      maxc = max(maxc, self%slot_count(s))
    end do
    e = 0
    do r = 1, n_grid
      do k3 = self%r_lo(3, r), self%r_hi(3, r)
        do k2 = self%r_lo(2, r), self%r_hi(2, r)
          do k1 = self%r_lo(1, r), self%r_hi(1, r)
            e = e + 1
            s = self%entry_slot(e)
            k = self%slot_fill(s)
            self%slot_fill(s) = k + 1
            self%cell_body(k) = r
            flags = 0
            if (k1 == self%r_lo(1, r)) flags = ibset(flags, 0)
            if (k2 == self%r_lo(2, r)) flags = ibset(flags, 1)
            if (k3 == self%r_lo(3, r)) flags = ibset(flags, 2)
            if (self%r_static(r)) flags = ibset(flags, 3)
            self%cell_flags(k) = flags
          end do
        end do
      end do
    end do

    call build_hierarchy(self, nl)

    self%last = bucket_stats_t()
    self%last%n_bodies = n
    self%last%n_grid = n_grid
    self%last%n_large = nl
    self%last%n_entries = n_entries
    self%last%cells_used = cells
    self%last%max_per_cell = maxc
    self%last%table_size = tsize
    self%last%dense = self%dense
    self%built = .true.
  end subroutine grid_build

  !> Orders the grid bodies by first box, lexicographic (k, j, i) on the low 10 bits of each
  !> coordinate relative to kmin: three stable counting-sort passes of 1024 buckets, one per
  !> axis, O(n). Only speed depends on this order, never the result.
  subroutine sort_order_spatially(self, ng)
    type(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: ng
    integer, allocatable :: key(:, :), perm(:), cnt(:)
    integer :: k, d, axis, acc, t
    if (ng < 2) return
    allocate (key(3, ng), perm(ng), cnt(0:1023))
    do k = 1, ng
      key(:, k) = int(iand(self%lo(:, self%order(k)) - self%kmin, 1023_i8))
    end do
    do axis = 1, 3
      cnt = 0
      do k = 1, ng
        cnt(key(axis, k)) = cnt(key(axis, k)) + 1
      end do
      acc = 1
      do d = 0, 1023
        t = cnt(d)
        cnt(d) = acc
        acc = acc + t
      end do
      do k = 1, ng   ! perm(new position) = old position
        d = key(axis, k)
        perm(cnt(d)) = k
        cnt(d) = cnt(d) + 1
      end do
      self%order(1:ng) = self%order(perm)
      key = key(:, perm)
    end do
  end subroutine sort_order_spatially

  subroutine ensure_body_arrays(self, n)
    type(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: n
    if (allocated(self%lower)) then
      if (size(self%lower, 2) >= n) return
      deallocate (self%lower, self%upper, self%is_static, self%in_grid, self%lo, self%hi)
    end if
    allocate (self%lower(3, n), self%upper(3, n), self%is_static(n), self%in_grid(n), &
              self%lo(3, n), self%hi(3, n))
  end subroutine ensure_body_arrays

  subroutine ensure_table(self, tsize, n_entries)
    type(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: tsize, n_entries
    logical :: grow
    grow = .not. allocated(self%slot_count)
    if (.not. grow) grow = size(self%slot_count) < tsize
    if (grow) then
      if (allocated(self%slot_count)) deallocate (self%slot_count, self%slot_start, self%slot_fill)
      allocate (self%slot_count(tsize), self%slot_start(tsize), self%slot_fill(tsize))
    end if
    if (.not. self%dense) then   ! keys only in hash mode
      grow = .not. allocated(self%slot_key)
      if (.not. grow) grow = size(self%slot_key, 2) < tsize
      if (grow) then
        if (allocated(self%slot_key)) deallocate (self%slot_key)
        allocate (self%slot_key(3, tsize))
      end if
    end if
    grow = .not. allocated(self%cell_body)
    if (.not. grow) grow = size(self%cell_body) < n_entries
    if (grow) then
      if (allocated(self%cell_body)) deallocate (self%cell_body, self%entry_slot, self%cell_flags)
      allocate (self%cell_body(max(1, n_entries)), self%entry_slot(max(1, n_entries)), &
                self%cell_flags(max(1, n_entries)))
    end if
  end subroutine ensure_table

  !> Flat bounding volume hierarchy over the nl large bodies: median split of box centres
  !> along the longest axis of the node's centre bounds, built with an explicit stack.
  !> Rebuilt by every build: O(nl log nl), nothing for a handful of walls.
  subroutine build_hierarchy(self, nl)
    type(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: nl
    integer :: i, k, first, cnt, mid, axis, top, nd
    integer :: stack(STACK_SIZE)
    real(dp) :: cmin(3), cmax(3)
    real(dp), allocatable :: key(:)

    self%n_large = nl
    self%n_large_dynamic = 0
    self%n_nodes = 0
    if (allocated(self%large_ids)) then
      if (size(self%large_ids) < nl) deallocate (self%large_ids, self%node_lower, self%node_upper, &
                                                 self%node_first, self%node_count)
    end if
    if (.not. allocated(self%large_ids)) then
      allocate (self%large_ids(max(1, nl)), self%node_lower(3, max(1, 2*nl)), self%node_upper(3, max(1, 2*nl)), &
                self%node_first(max(1, 2*nl)), self%node_count(max(1, 2*nl)))
    end if
    if (nl == 0) return
    k = 0
    do i = 1, self%n
      if (self%in_grid(i)) cycle
      k = k + 1
      self%large_ids(k) = i
      if (.not. self%is_static(i)) self%n_large_dynamic = self%n_large_dynamic + 1
    end do
    allocate (key(nl))
    nd = 1
    self%node_first(1) = 1
    self%node_count(1) = nl
    top = 1
    stack(1) = 1
    do while (top > 0)
      k = stack(top)
      top = top - 1
      first = self%node_first(k)
      cnt = self%node_count(k)
      self%node_lower(:, k) = minval(self%lower(:, self%large_ids(first:first + cnt - 1)), dim=2)
      self%node_upper(:, k) = maxval(self%upper(:, self%large_ids(first:first + cnt - 1)), dim=2)
      if (cnt <= LEAF_SIZE) cycle
      cmin = huge(1.0_dp)
      cmax = -huge(1.0_dp)
      do i = first, first + cnt - 1
        cmin = min(cmin, 0.5_dp*(self%lower(:, self%large_ids(i)) + self%upper(:, self%large_ids(i))))
        cmax = max(cmax, 0.5_dp*(self%lower(:, self%large_ids(i)) + self%upper(:, self%large_ids(i))))
      end do
      axis = maxloc(cmax - cmin, dim=1)
      do i = 1, cnt
        key(i) = 0.5_dp*(self%lower(axis, self%large_ids(first + i - 1)) + self%upper(axis, self%large_ids(first + i - 1)))
      end do
      mid = cnt/2
      call select_kth(self%large_ids(first:first + cnt - 1), key(1:cnt), mid)
      ! children nd+1 (first half) and nd+2 (second half)
      self%node_first(nd + 1) = first
      self%node_count(nd + 1) = mid
      self%node_first(nd + 2) = first + mid
      self%node_count(nd + 2) = cnt - mid
      self%node_first(k) = nd + 1
      self%node_count(k) = 0
      stack(top + 1) = nd + 1
      stack(top + 2) = nd + 2
      top = top + 2
      nd = nd + 2
    end do
    self%n_nodes = nd
  end subroutine build_hierarchy

  pure logical function boxes_overlap(al, au, bl, bu)
    real(dp), intent(in) :: al(3), au(3), bl(3), bu(3)
    boxes_overlap = al(1) <= bu(1) .and. bl(1) <= au(1) .and. al(2) <= bu(2) .and. bl(2) <= au(2) .and. &
                    al(3) <= bu(3) .and. bl(3) <= au(3)
  end function boxes_overlap

  !> Candidate pairs (pairs(1,p) < pairs(2,p), unique, sorted by (first, second)) of bodies
  !> whose boxes lie within `rings` boxes of each other and whose bounding boxes, body i's
  !> inflated by margin(i) [m] on every side, overlap. margin has size n or 1 (same for all).
  !> Margins must reach no further than the rings: m_i + m_j <= rings*h for grid bodies, so
  !> that the ring limit never drops an overlapping pair (then the result equals brute force
  !> inflated-box overlap). Time of contact: rings = 2, margin = each body's displacement bound
  !> for the step (<= h); intersection and contact checks: rings = 1, margins <= h/2.
  !> Pairs with a large body (static or not) come from the hierarchy and have no ring limit.
  !> pairs is grown when too small, never shrunk, so a caller's buffer is reused.
  !> n_owned (MPI): bodies 1..n_owned are owned, the rest ghosts; pairs of two ghosts are
  !> dropped (their owner reports them). Default: all bodies owned.
  subroutine grid_candidate_pairs(self, rings, margin, pairs, n_pairs, err, n_owned)
    class(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: rings
    real(dp), intent(in) :: margin(:)
    integer, allocatable, intent(inout) :: pairs(:, :)
    integer, intent(out) :: n_pairs
    type(error_t), intent(inout) :: err
    integer, intent(in), optional :: n_owned
    integer :: i, j, e, s, np, n, k, r, top, l, stack(STACK_SIZE), owned
    integer(i8) :: c(3), slo(3), shi(3), k1, k2, k3, tested
    real(dp) :: m1, m2, mi, mj, m_grid, m_large, d, ql(3), qu(3), il(3), iu(3)
    logical :: uniform, static_i
    integer(int8) :: flags
    character(len=96) :: buf

    n_pairs = 0
    if (.not. self%built) then
      call err%set(ERR_INPUT, 'bucket grid: candidate_pairs called before build')
      return
    end if
    n = self%n
    if (rings < 1) then
      write (buf, '(i0)') rings
      call err%set(ERR_INPUT, 'bucket grid: rings = '//trim(buf)//' must be >= 1')
      return
    end if
    uniform = size(margin) == 1
    if (.not. uniform .and. size(margin) < n) then
      write (buf, '(a,i0,a,i0)') 'size(margin) = ', size(margin), ' but n = ', n
      call err%set(ERR_INPUT, 'bucket grid: '//trim(buf)//' (give one margin or one per body)')
      return
    end if
    ! Largest two grid margins: their sum must stay within the ring reach.
    m1 = 0.0_dp
    m2 = 0.0_dp
    m_large = 0.0_dp
    do i = 1, n
      mi = margin_of(i)
      if (.not. (mi >= 0.0_dp .and. mi <= huge(1.0_dp))) then
        write (buf, '(i0)') i
        call err%set(ERR_INPUT, 'bucket grid: margin of body '//trim(buf)//' is negative or not finite')
        return
      end if
      if (self%in_grid(i)) then
        if (mi > m1) then
          m2 = m1
          m1 = mi
        else if (mi > m2) then
          m2 = mi
        end if
      else
        m_large = max(m_large, mi)
      end if
    end do
    if (m1 + m2 > rings*self%h) then
      write (buf, '(es11.4,a,es11.4)') m1 + m2, ' m exceeds rings*box size = ', rings*self%h
      call err%set(ERR_INPUT, 'bucket grid: two margins sum to '//trim(buf)// &
                   ' m: pairs could be missed (raise rings or the box size, or lower the margins)')
      return
    end if
    m_grid = m1
    owned = n
    if (present(n_owned)) owned = max(0, min(n, n_owned))

    np = 0
    tested = 0
    if (.not. allocated(self%pair_buf)) allocate (self%pair_buf(2, max(16, 4*n)))
    ! Grid pairs, visiting the grid bodies by rank; each pair is found from its lower rank.
    do k = 1, self%last%n_grid
      self%r_margin(k) = margin_of(self%order(k))
    end do
    do k = 1, self%last%n_grid
      i = self%order(k)
      static_i = self%r_static(k)
      mi = self%r_margin(k)
      il = self%r_lower(:, k) - mi
      iu = self%r_upper(:, k) + mi
      ! Boxes of the box inflated by m_i + max m_j (widened by a few ulps so rounding in
      ! floor() never drops a pair brute force keeps), capped at the rings and clipped to the
      ! occupied boxes.
      d = mi + m_grid
      ql = (self%r_lower(:, k) - d) - 4.0_dp*spacing(abs(self%r_lower(:, k)) + d)
      qu = (self%r_upper(:, k) + d) + 4.0_dp*spacing(abs(self%r_upper(:, k)) + d)
      slo = max(floor((ql - self%origin)*self%inv_h, kind=i8), self%r_lo(:, k) - rings)
      shi = min(floor((qu - self%origin)*self%inv_h, kind=i8), self%r_hi(:, k) + rings)
      slo = max(slo, self%kmin)
      shi = min(shi, self%kmax)
      do k3 = slo(3), shi(3)
        do k2 = slo(2), shi(2)
          do k1 = slo(1), shi(1)
            c = [k1, k2, k3]
            s = find_slot(self, c)
            if (s == 0) cycle
            do e = self%slot_start(s), self%slot_start(s) + self%slot_count(s) - 1
              r = self%cell_body(e)
              if (r <= k) cycle
              flags = self%cell_flags(e)
              if (static_i .and. btest(flags, 3)) cycle
              ! Report j only in the first box (lowest corner) of its range inside i's
              ! search range, max(lo_j, slo): each pair is tested once, without a visited
              ! set. Per axis that box is the window's first layer or j's own first layer.
              if (.not. ((k1 == slo(1) .or. btest(flags, 0)) .and. (k2 == slo(2) .or. btest(flags, 1)) .and. &
                         (k3 == slo(3) .or. btest(flags, 2)))) cycle
              tested = tested + 1
              mj = self%r_margin(r)
              if (il(1) <= self%r_upper(1, r) + mj .and. self%r_lower(1, r) - mj <= iu(1) .and. &
                  il(2) <= self%r_upper(2, r) + mj .and. self%r_lower(2, r) - mj <= iu(2) .and. &
                  il(3) <= self%r_upper(3, r) + mj .and. self%r_lower(3, r) - mj <= iu(3)) then
                j = self%order(r)
                call push(min(i, j), max(i, j))
              end if
            end do
          end do
        end do
      end do
    end do
    ! Large bodies: grid bodies query the hierarchy (static ones only if some large body
    ! moves); large dynamic bodies query it for other large bodies.
    if (self%n_large > 0) then
      do i = 1, n
        if (self%is_static(i) .and. (self%n_large_dynamic == 0 .or. .not. self%in_grid(i))) cycle
        mi = margin_of(i)
        il = self%lower(:, i) - mi
        iu = self%upper(:, i) + mi
        ql = il - m_large
        qu = iu + m_large
        top = 1
        stack(1) = 1
        do while (top > 0)
          k = stack(top)
          top = top - 1
          if (.not. boxes_overlap(ql, qu, self%node_lower(:, k), self%node_upper(:, k))) cycle
          if (self%node_count(k) == 0) then
            stack(top + 1) = self%node_first(k)
            stack(top + 2) = self%node_first(k) + 1
            top = top + 2
            cycle
          end if
          do l = self%node_first(k), self%node_first(k) + self%node_count(k) - 1
            j = self%large_ids(l)
            if (j == i) cycle
            if (self%is_static(i) .and. self%is_static(j)) cycle
            ! large-large pairs are found from both sides: keep the one from the smaller
            ! index (a static large body never queries, so its partner always reports it).
            if (.not. self%in_grid(i) .and. .not. self%is_static(j) .and. j < i) cycle
            tested = tested + 1
            mj = margin_of(j)
            if (il(1) <= self%upper(1, j) + mj .and. self%lower(1, j) - mj <= iu(1) .and. &
                il(2) <= self%upper(2, j) + mj .and. self%lower(2, j) - mj <= iu(2) .and. &
                il(3) <= self%upper(3, j) + mj .and. self%lower(3, j) - mj <= iu(3)) &
              call push(min(i, j), max(i, j))
          end do
        end do
      end do
    end if

    call sort_pairs(self, np, n)
    if (allocated(pairs)) then
      if (size(pairs, 1) /= 2 .or. size(pairs, 2) < np) deallocate (pairs)
    end if
    if (.not. allocated(pairs)) allocate (pairs(2, max(1, np)))
    pairs(:, 1:np) = self%pair_buf(:, 1:np)
    n_pairs = np
    self%last%pairs_tested = tested
    self%last%pairs_returned = np

  contains

    pure real(dp) function margin_of(b)
      integer, intent(in) :: b
      if (uniform) then
        margin_of = margin(1)
      else
        margin_of = margin(b)
      end if
    end function margin_of

    subroutine push(a, b)
      integer, intent(in) :: a, b
      integer, allocatable :: grown(:, :)
      if (a > owned) return   ! a < b: both are ghosts
      if (np == size(self%pair_buf, 2)) then
        allocate (grown(2, 2*np))
        grown(:, 1:np) = self%pair_buf(:, 1:np)
        call move_alloc(grown, self%pair_buf)
      end if
      np = np + 1
      self%pair_buf(1, np) = a
      self%pair_buf(2, np) = b
    end subroutine push

  end subroutine grid_candidate_pairs

  !> Sorts pair_buf(:,1:np) by (first, second): two stable counting-sort passes (by second,
  !> then by first), O(n + np), so the order never depends on the hash table or the hierarchy.
  subroutine sort_pairs(self, np, n)
    type(bucket_grid_t), intent(inout) :: self
    integer, intent(in) :: np, n
    integer :: p, pass, key, acc, t
    if (np <= 1) return
    if (allocated(self%pair_tmp)) then
      if (size(self%pair_tmp, 2) < np) deallocate (self%pair_tmp)
    end if
    if (.not. allocated(self%pair_tmp)) allocate (self%pair_tmp(2, size(self%pair_buf, 2)))
    if (allocated(self%counts)) then
      if (size(self%counts) < n + 1) deallocate (self%counts)
    end if
    if (.not. allocated(self%counts)) allocate (self%counts(n + 1))
    do pass = 2, 1, -1
      self%counts(1:n + 1) = 0
      do p = 1, np
        key = self%pair_buf(pass, p)
        self%counts(key) = self%counts(key) + 1
      end do
      acc = 1
      do key = 1, n
        t = self%counts(key)
        self%counts(key) = acc
        acc = acc + t
      end do
      do p = 1, np
        key = self%pair_buf(pass, p)
        self%pair_tmp(:, self%counts(key)) = self%pair_buf(:, p)
        self%counts(key) = self%counts(key) + 1
      end do
      self%pair_buf(:, 1:np) = self%pair_tmp(:, 1:np)
    end do
  end subroutine sort_pairs

end module bucket_grid
