!> Islands: which bodies move together.
!>
!>  - Contact groups: the connected components of a set of contacts through moving bodies
!>    (a fixed body connects nothing), solved together by the impulse and contact solvers.
!>  - Body islands: the components of a set of body pairs among given bodies (sleeping: an
!>    island of bodies in the contact band falls asleep whole).
!>  - The islands of the local event loop (island_table_t): bodies held by the same contact
!>    pass, stepping together on their own clock (the start and length of their current
!>    step), while every other island and every free body does not step with them.
!> Everything here costs what its contacts or members cost, never the size of the scene:
!> components by a union-find over a local numbering of the bodies involved.
module islands
  use kinds, only: dp
  use body_state, only: bodies_t
  use contact_point, only: contact_t
  use sorting, only: sort_index_real
  implicit none
  private
  public :: contact_groups, group_members, body_islands, find_root, unite, island_t, island_table_t

  !> One island of the local event loop: its bodies and its clock.
  type :: island_t
    integer, allocatable :: members(:)   !< body indices, in increasing global id
    integer :: n = 0
    real(dp) :: t_start = 0.0_dp         !< its step started here [s]
    real(dp) :: step = 0.0_dp            !< and ends at t_start + step [s]
    real(dp) :: pass_step = 0.0_dp       !< the step its contact pass was solved for [s] (>= step)
    logical :: live = .false.
    integer, allocatable :: band_pairs(:, :)  !< its pass's pairs in the contact band (sleeping)
    integer :: n_band_pairs = 0
  end type island_t

  !> The islands of the local loop, by slot; slots of ended islands are reused.
  type :: island_table_t
    type(island_t), allocatable :: islands(:)
    integer, allocatable :: free_slots(:)
    integer :: n_free = 0
    integer :: n_slots = 0
    integer :: n_live = 0
  contains
    procedure :: init => table_init
    procedure :: add => table_add
    procedure :: remove => table_remove
    procedure :: append => table_append
    procedure :: remap_bodies => table_remap_bodies
  end type island_table_t

contains

  subroutine table_init(self)
    class(island_table_t), intent(inout) :: self
    if (allocated(self%islands)) deallocate (self%islands, self%free_slots)
    allocate (self%islands(16), self%free_slots(16))
    self%n_free = 0
    self%n_slots = 0
    self%n_live = 0
  end subroutine table_init

  !> A new island of members(:) stepping over [t_start, t_start + step]; returns its slot.
  integer function table_add(self, members, t_start, step, pass_step) result(slot)
    class(island_table_t), intent(inout) :: self
    integer, intent(in) :: members(:)
    real(dp), intent(in) :: t_start, step, pass_step
    type(island_t), allocatable :: grown(:)
    integer :: k
    if (.not. allocated(self%islands)) call self%init()
    if (self%n_free > 0) then
      slot = self%free_slots(self%n_free)
      self%n_free = self%n_free - 1
    else
      if (self%n_slots == size(self%islands)) then
        allocate (grown(2*size(self%islands)))
        do k = 1, self%n_slots
          call move_alloc(self%islands(k)%members, grown(k)%members)
          grown(k)%n = self%islands(k)%n
          grown(k)%t_start = self%islands(k)%t_start
          grown(k)%step = self%islands(k)%step
          grown(k)%pass_step = self%islands(k)%pass_step
          grown(k)%live = self%islands(k)%live
          if (allocated(self%islands(k)%band_pairs)) call move_alloc(self%islands(k)%band_pairs, grown(k)%band_pairs)
          grown(k)%n_band_pairs = self%islands(k)%n_band_pairs
        end do
        call move_alloc(grown, self%islands)
      end if
      self%n_slots = self%n_slots + 1
      slot = self%n_slots
    end if
    self%islands(slot)%members = members
    self%islands(slot)%n = size(members)
    self%islands(slot)%t_start = t_start
    self%islands(slot)%step = step
    self%islands(slot)%pass_step = pass_step
    self%islands(slot)%live = .true.
    self%n_live = self%n_live + 1
  end function table_add

  !> More members for island slot (they join its current step).
  subroutine table_append(self, slot, members)
    class(island_table_t), intent(inout) :: self
    integer, intent(in) :: slot, members(:)
    integer, allocatable :: grown(:)
    associate (isl => self%islands(slot))
      if (isl%n + size(members) > size(isl%members)) then
        allocate (grown(max(2*size(isl%members), isl%n + size(members))))
        grown(1:isl%n) = isl%members(1:isl%n)
        call move_alloc(grown, isl%members)
      end if
      isl%members(isl%n + 1:isl%n + size(members)) = members
      isl%n = isl%n + size(members)
    end associate
  end subroutine table_append

  !> The bodies were renumbered (a migration): body i is now new_index(i), 0 if it left.
  !> Every live island's members and band pairs are renamed, each island keeping its slot
  !> and clock, if none of them left; otherwise nothing is changed and kept is false (an
  !> island split between ranks: the caller ends it another way).
  subroutine table_remap_bodies(self, new_index, kept)
    class(island_table_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    logical, intent(out) :: kept
    integer :: slot, k
    kept = .true.
    if (.not. allocated(self%islands)) return
    do slot = 1, self%n_slots
      associate (isl => self%islands(slot))
        if (.not. isl%live) cycle
        if (any(new_index(isl%members(1:isl%n)) == 0)) kept = .false.
        do k = 1, isl%n_band_pairs
          if (any(new_index(isl%band_pairs(:, k)) == 0)) kept = .false.
        end do
      end associate
      if (.not. kept) return
    end do
    do slot = 1, self%n_slots
      associate (isl => self%islands(slot))
        if (.not. isl%live) cycle
        isl%members(1:isl%n) = new_index(isl%members(1:isl%n))
        do k = 1, isl%n_band_pairs
          isl%band_pairs(:, k) = new_index(isl%band_pairs(:, k))
        end do
      end associate
    end do
  end subroutine table_remap_bodies

  subroutine table_remove(self, slot)
    class(island_table_t), intent(inout) :: self
    integer, intent(in) :: slot
    integer, allocatable :: grown(:)
    if (.not. self%islands(slot)%live) return
    self%islands(slot)%live = .false.
    self%islands(slot)%n = 0
    if (self%n_free == size(self%free_slots)) then
      allocate (grown(2*size(self%free_slots)))
      grown(1:self%n_free) = self%free_slots(1:self%n_free)
      call move_alloc(grown, self%free_slots)
    end if
    self%n_free = self%n_free + 1
    self%free_slots(self%n_free) = slot
    self%n_live = self%n_live - 1
  end subroutine table_remove

  !> The components of bodies(1:n) joined by pairs(:, 1:n_pairs) (pairs naming other bodies
  !> are ignored): root(k) is the position in bodies of component k's first body, label(m)
  !> the component of bodies(m) (1..n_components, in order of first body).
  subroutine body_islands(bodies_list, n, pairs, n_pairs, label, n_components)
    integer, intent(in) :: bodies_list(:), n, pairs(:, :), n_pairs
    integer, allocatable, intent(out) :: label(:)
    integer, intent(out) :: n_components
    integer, allocatable :: parent(:), order(:), first(:)
    integer :: k, m, a, b, root
    ! local numbers by binary search in the sorted list
    allocate (parent(n), label(n), first(n))
    order = sorted_positions(bodies_list(1:n))
    parent = [(k, k=1, n)]
    do k = 1, n_pairs
      a = position_of(pairs(1, k))
      b = position_of(pairs(2, k))
      if (a == 0 .or. b == 0) cycle
      call unite(parent, a, b)
    end do
    first = 0
    n_components = 0
    do m = 1, n
      root = find_root(parent, m)
      if (first(root) == 0) then
        n_components = n_components + 1
        first(root) = n_components
      end if
      label(m) = first(root)
    end do
  contains
    integer function position_of(body)
      integer, intent(in) :: body
      integer :: lo, hi, mid
      position_of = 0
      lo = 1
      hi = n
      do while (lo <= hi)
        mid = (lo + hi)/2
        if (bodies_list(order(mid)) == body) then
          position_of = order(mid)
          return
        else if (bodies_list(order(mid)) < body) then
          lo = mid + 1
        else
          hi = mid - 1
        end if
      end do
    end function position_of
  end subroutine body_islands

  !> The permutation that sorts a list of integers ascending.
  function sorted_positions(values) result(order)
    integer, intent(in) :: values(:)
    integer, allocatable :: order(:)
    call sort_index_real(real(values, dp), order)
  end function sorted_positions

  !> The groups of a set of contacts: connected components through moving bodies (a fixed
  !> body connects nothing; a contact between two fixed bodies is in no group). Group k holds
  !> contacts group_list(group_start(k):group_start(k+1)-1), in increasing index; groups come
  !> in the order of their first contact. Cost O(m log m) for m contacts, whatever the size
  !> of the scene (a floor under 10,000 separate boxes is 10,000 groups per step).
  subroutine contact_groups(bodies, contacts, group_start, group_list, n_groups)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    integer, allocatable, intent(out) :: group_start(:)   !< (n_groups + 1)
    integer, allocatable, intent(out) :: group_list(:)    !< contact indices, group by group
    integer, intent(out) :: n_groups
    integer, allocatable :: members(:), side(:, :), parent(:), group_of(:), size_of(:), fill(:)
    integer :: n_members, c, m, root
    m = size(contacts)
    call group_members(bodies, contacts, members, n_members, side)
    ! union-find over the local numbering of the moving bodies
    allocate (parent(n_members))
    parent = [(c, c=1, n_members)]
    do c = 1, m
      if (side(1, c) > 0 .and. side(2, c) > 0) call unite(parent, side(1, c), side(2, c))
    end do
    ! groups numbered in the order of their first contact
    allocate (group_of(m), size_of(n_members + 1), fill(n_members))
    fill = 0          ! group number of each root, once seen
    size_of = 0
    n_groups = 0
    do c = 1, m
      group_of(c) = 0
      if (side(1, c) == 0 .and. side(2, c) == 0) cycle
      root = find_root(parent, max(side(1, c), side(2, c)))
      if (fill(root) == 0) then
        n_groups = n_groups + 1
        fill(root) = n_groups
      end if
      group_of(c) = fill(root)
      size_of(group_of(c)) = size_of(group_of(c)) + 1
    end do
    allocate (group_start(n_groups + 1), group_list(count(group_of > 0)))
    group_start(1) = 1
    do c = 1, n_groups
      group_start(c + 1) = group_start(c) + size_of(c)
    end do
    fill(1:n_groups) = group_start(1:n_groups)
    do c = 1, m
      if (group_of(c) == 0) cycle
      group_list(fill(group_of(c))) = c
      fill(group_of(c)) = fill(group_of(c)) + 1
    end do
  end subroutine contact_groups

  !> The moving bodies of a set of contacts, each once, in order of first appearance
  !> (members(1:n_members), indices into bodies), and side(1:2, c): the position in members
  !> of contact c's body a and body b (0 for a fixed body). Sorting, not a table the size of
  !> the scene: O(m log m) for m contacts (called once per contact group and step).
  subroutine group_members(bodies, contacts, members, n_members, side)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    integer, allocatable, intent(out) :: members(:)
    integer, intent(out) :: n_members
    integer, allocatable, intent(out) :: side(:, :)
    integer, allocatable :: order(:), first(:), run_of(:)
    real(dp), allocatable :: ids(:)
    integer :: m, k, p, n_runs
    m = size(contacts)
    allocate (side(2, m), ids(2*m))
    side = 0
    ! the sides in order a1, b1, a2, b2, ...; fixed bodies sort first, as 0
    do k = 1, m
      ids(2*k - 1) = merge(real(contacts(k)%a, dp), 0.0_dp, moving(bodies, contacts(k)%a))
      ids(2*k) = merge(real(contacts(k)%b, dp), 0.0_dp, moving(bodies, contacts(k)%b))
    end do
    call sort_index_real(ids, order)
    ! runs of one body; the sort is stable, so a run's first entry is its first appearance
    allocate (first(2*m), run_of(2*m))
    n_runs = 0
    do k = 1, 2*m
      p = order(k)
      if (ids(p) == 0.0_dp) cycle
      if (k == 1) then
        n_runs = n_runs + 1
        first(n_runs) = p
      else if (ids(order(k - 1)) /= ids(p)) then
        n_runs = n_runs + 1
        first(n_runs) = p
      end if
      run_of(p) = n_runs
    end do
    ! members in order of first appearance
    call sort_index_real(real(first(1:n_runs), dp), order)
    n_members = n_runs
    allocate (members(n_members))
    do k = 1, n_members
      members(k) = nint(ids(first(order(k))))
      first(order(k)) = k          ! a run's position in members, from here on
    end do
    do p = 1, 2*m
      if (ids(p) == 0.0_dp) cycle
      side(2 - mod(p, 2), (p + 1)/2) = first(run_of(p))
    end do
  end subroutine group_members

  pure logical function moving(bodies, i)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    moving = .not. bodies%fixed(i)
  end function moving

  !> Union-find over body indices (contact groups): the root of i's set, with path compression.
  recursive integer function find_root(parent, i) result(root)
    integer, intent(inout) :: parent(:)
    integer, intent(in) :: i
    if (parent(i) == i) then
      root = i
    else
      root = find_root(parent, parent(i))
      parent(i) = root
    end if
  end function find_root

  !> Joins the sets of i and j (the smaller index becomes the root: order-free groups).
  subroutine unite(parent, i, j)
    integer, intent(inout) :: parent(:)
    integer, intent(in) :: i, j
    integer :: ri, rj
    ri = find_root(parent, i)
    rj = find_root(parent, j)
    if (ri /= rj) parent(max(ri, rj)) = min(ri, rj)
  end subroutine unite

end module islands
