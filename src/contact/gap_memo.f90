!> The last closest-point query of each pair, kept so that the same query is not made
!> twice. The local event loop asks for the same gap again often: a certificate that
!> conservative advancement ended at a measured time t is due at t, and certifying it again
!> there starts with the gap at t, the poses bitwise those of the advancement's last query
!> (9% of the queries of a 1000-cube gas). A query is a pure function of the two shapes and
!> the two poses, so an entry answers only a query with the same bodies, the same shapes and
!> bitwise the same positions and orientations: the answer is the one pair_gap would give.
!>
!> One entry per hash slot of the pair (i, j), overwritten by the next pair that lands there:
!> a pair's last query is what is asked again, and collisions only cost a query.
module gap_memo
  use kinds, only: dp, i8
  use shape, only: shape_library_t, SHAPE_SPHERE
  use body_state, only: bodies_t
  use pair_geometry, only: pair_gap
  use mesh_distance, only: feature_pair_t
  implicit none
  private
  public :: gap_memo_t

  integer, parameter :: n_slots = 4096        !< a power of two
  integer, parameter :: key_words = 14        !< xi(3), qi(4), xj(3), qj(4)

  type :: gap_memo_t
    integer, allocatable :: ids(:, :)          !< (4, n_slots) i, j, shape of i, shape of j; 0: empty
    integer(i8), allocatable :: pose(:, :)     !< (key_words, n_slots) the poses' bits
    real(dp), allocatable :: gap(:)            !< [m]
    real(dp), allocatable :: normal(:, :)      !< (3, n_slots) unit, from i to j
    !> (n_slots) the primitive pair that realised the gap: the next query of the same pair
    !> at other poses starts from it (a bound only: the answer is the same without it)
    type(feature_pair_t), allocatable :: hint(:)
    integer(i8) :: hits = 0, misses = 0
  contains
    procedure :: pair_gap => memo_pair_gap
    procedure :: clear => memo_clear
  end type gap_memo_t

contains

  !> Empties the memo (a new scene: shape ids and body indices may mean other things).
  subroutine memo_clear(self)
    class(gap_memo_t), intent(inout) :: self
    if (allocated(self%ids)) self%ids = 0
    self%hits = 0
    self%misses = 0
  end subroutine memo_clear

  !> pair_gap (pair_geometry) of bodies i and j at the given poses, from the memo when the
  !> same query was the last one made in its slot.
  subroutine memo_pair_gap(self, shapes, bodies, i, j, xi, qi, xj, qj, gap, normal)
    class(gap_memo_t), intent(inout) :: self
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    real(dp), intent(in) :: xi(3), qi(4), xj(3), qj(4)
    real(dp), intent(out) :: gap, normal(3)
    integer(i8) :: key(key_words)
    integer :: slot, k
    logical :: same
    ! two spheres: the gap is a few operations, cheaper than looking it up
    if (shapes%shapes(bodies%shape_id(i))%kind == SHAPE_SPHERE .and. &
        shapes%shapes(bodies%shape_id(j))%kind == SHAPE_SPHERE) then
      call pair_gap(shapes, bodies, i, j, xi, qi, xj, qj, gap, normal)
      return
    end if
    if (.not. allocated(self%ids)) then
      allocate (self%ids(4, n_slots), self%pose(key_words, n_slots), self%gap(n_slots), self%normal(3, n_slots), &
                self%hint(n_slots))
      self%ids = 0
    end if
    key(1:3) = transfer(xi, key(1:3))
    key(4:7) = transfer(qi, key(4:7))
    key(8:10) = transfer(xj, key(8:10))
    key(11:14) = transfer(qj, key(11:14))
    slot = int(iand(int(i, i8)*73856093_i8 + int(j, i8)*19349663_i8, int(n_slots - 1, i8))) + 1
    same = self%ids(1, slot) == i .and. self%ids(2, slot) == j .and. &
           self%ids(3, slot) == bodies%shape_id(i) .and. self%ids(4, slot) == bodies%shape_id(j)
    if (same) then
      do k = 1, key_words
        if (self%pose(k, slot) /= key(k)) then
          same = .false.
          exit
        end if
      end do
    end if
    if (same) then
      gap = self%gap(slot)
      normal = self%normal(:, slot)
      self%hits = self%hits + 1
      return
    end if
    ! the same pair at other poses: its last pair of features is a good first bound
    if (.not. (self%ids(1, slot) == i .and. self%ids(2, slot) == j .and. &
               self%ids(3, slot) == bodies%shape_id(i) .and. self%ids(4, slot) == bodies%shape_id(j))) &
      self%hint(slot) = feature_pair_t()
    call pair_gap(shapes, bodies, i, j, xi, qi, xj, qj, gap, normal, self%hint(slot))
    self%misses = self%misses + 1
    self%ids(:, slot) = [i, j, bodies%shape_id(i), bodies%shape_id(j)]
    self%pose(:, slot) = key
    self%gap(slot) = gap
    self%normal(:, slot) = normal
  end subroutine memo_pair_gap

end module gap_memo
