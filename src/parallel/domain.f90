!> The domain decomposition of a scene over ranks, without MPI (parallel_env will make the
!> calls; this module only says who owns what, so it is unit-tested in one process).
!>
!> Grid boxes are those of the moving broad phase (contact/cell_grid): cubes of edge h,
!> box k along an axis covering [k h, (k+1) h), found as floor(x*(1/h)) with the same
!> arithmetic, so a body's box here is its box there. The global box is the range of grid
!> boxes holding the scene's bounds. It is cut into bricks of whole boxes, one per rank of
!> a dims(1) x dims(2) x dims(3) grid of ranks:
!>
!> - **Ranks and coordinates** follow MPI_Cart_create with periods = .false. (row-major:
!>   the last coordinate varies fastest): rank = (c1*dims(2) + c2)*dims(3) + c3 with
!>   0-based coordinates. The MPI wrapper passes the rank of its Cartesian communicator, so
!>   MPI_Cart_coords and MPI_Cart_shift agree with coords_of and face_neighbour.
!> - **Bricks.** Along an axis with n boxes and p ranks, coordinate c holds the boxes
!>   lo + floor(n c/p) .. lo + floor(n (c+1)/p) - 1 (counts differ by at most one). An
!>   axis split over p > 1 ranks needs at least two boxes per rank, so that the two halo
!>   rings on a side all come from the face neighbour (the staged exchange below); an
!>   axis with one rank has no neighbours along it and needs only one box.
!> - **Owner.** A point (a body's centre of mass) belongs to the brick of its box: a point
!>   exactly on a box face lies in the upper box (floor), so on a brick face it belongs to
!>   the upper brick, on an edge or corner to the brick above it along every such axis;
!>   every point has exactly one owner. Points outside the global box clamp to the edge
!>   boxes (the scene's bounds are those at the start; bodies may leave them).
!> - **Halo.** The halo of `rings` rings (1 or 2) is the boxes within `rings` boxes of the
!>   brick along every axis (inside the global box) that are not in it: all 26 neighbours'
!>   boxes near the brick. One ring serves overlap and contact checks, two the time of
!>   contact.
!> - **Staged exchange.** Three passes, x then y then z; in the pass of an axis every rank
!>   sends to its two face neighbours along it (6 messages, not 26). What goes to the
!>   neighbour on side s of axis a (halo_send_boxes) is the `rings` outermost layers of
!>   the brick on that side, extended along the axes already exchanged (before a) by the
!>   halo received there, and the brick's range along the axes still to come: edges and
!>   corners arrive by forwarding, each halo box exactly once.
module domain
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INPUT, ERR_NUMERIC
  use string_utils, only: str
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite, ieee_is_nan
  implicit none
  private
  public :: domain_t, box_range_t, suggest_dims
  public :: NO_RANK, MAX_HALO_RINGS, MINUS_X, PLUS_X, MINUS_Y, PLUS_Y, MINUS_Z, PLUS_Z, direction_axis, &
            direction_side

  integer, parameter :: NO_RANK = -1          !< no rank there (MPI_PROC_NULL's role)
  integer, parameter :: MAX_HALO_RINGS = 2    !< rings are clamped to 0..2
  !> Directions of the staged exchange, in the order the messages are sent.
  integer, parameter :: MINUS_X = 1, PLUS_X = 2, MINUS_Y = 3, PLUS_Y = 4, MINUS_Z = 5, PLUS_Z = 6
  !> |box coordinate| limit: box indices stay exact as doubles (box_of clamps in reals).
  real(dp), parameter :: MAX_BOX_COORD = 2.0_dp**52
  character(len=1), parameter :: AXIS_NAME(3) = ['x', 'y', 'z']

  !> Boxes lo(d)..hi(d) along each axis d (empty when hi < lo somewhere).
  type :: box_range_t
    integer(i8) :: lo(3) = 0
    integer(i8) :: hi(3) = -1
  contains
    procedure :: is_empty => range_is_empty
    procedure :: n_boxes => range_n_boxes
    procedure :: holds => range_holds
  end type box_range_t

  type :: domain_t
    real(dp) :: h = 0.0_dp                 !< grid box edge [m]
    real(dp) :: inv_h = 0.0_dp
    !> |coordinate| [m] beyond which box_of clamps before scaling (2^54 boxes, or huge)
    real(dp) :: point_limit = 0.0_dp
    type(box_range_t) :: global            !< every box of the scene
    integer(i8) :: n_boxes(3) = 0          !< boxes along each axis
    integer :: dims(3) = 1                 !< ranks along each axis
    integer :: n_ranks = 1
    integer :: rank = 0                    !< this rank
    integer :: coords(3) = 0               !< its 0-based Cartesian coordinates
    type(box_range_t) :: own               !< its brick
  contains
    procedure :: init => domain_init
    procedure :: coords_of => domain_coords_of
    procedure :: rank_of => domain_rank_of
    procedure :: brick => domain_brick
    procedure :: box_of => domain_box_of
    procedure :: owner_of => domain_owner_of
    procedure :: owner_of_box => domain_owner_of_box
    procedure :: face_neighbour => domain_face_neighbour
    procedure :: neighbours => domain_neighbours
    procedure :: halo_region => domain_halo_region
    procedure :: in_halo => domain_in_halo
    procedure :: halo_send_boxes => domain_halo_send_boxes
  end type domain_t

contains

  !> The decomposition of the scene whose bounds are [lower, upper] [m] into bricks of grid
  !> boxes of edge box_size [m] over dims ranks, seen from rank `rank` (0-based).
  subroutine domain_init(self, box_size, lower, upper, dims, rank, err)
    class(domain_t), intent(inout) :: self
    real(dp), intent(in) :: box_size
    real(dp), intent(in) :: lower(3), upper(3)
    integer, intent(in) :: dims(3)
    integer, intent(in) :: rank
    type(error_t), intent(inout) :: err
    integer :: d
    integer(i8) :: n_ranks
    if (.not. ieee_is_finite(box_size) .or. box_size <= 0.0_dp) then
      call err%set(ERR_INPUT, 'domain: the grid box size must be finite and > 0 m, not '//str(box_size, '(es10.3)'))
      return
    end if
    if (.not. (all(ieee_is_finite(lower)) .and. all(ieee_is_finite(upper)))) then
      call err%set(ERR_NUMERIC, 'domain: the scene''s bounds are not finite (a position is NaN or Inf)')
      return
    end if
    if (any(lower > upper)) then
      call err%set(ERR_INPUT, 'domain: the scene''s lower bound exceeds its upper bound')
      return
    end if
    if (any(abs(lower)/box_size > MAX_BOX_COORD) .or. any(abs(upper)/box_size > MAX_BOX_COORD)) then
      call err%set(ERR_NUMERIC, 'domain: the scene reaches more than 2^52 grid boxes from the origin')
      return
    end if
    if (any(dims < 1)) then
      call err%set(ERR_INPUT, 'domain: every entry of dims must be >= 1, not '//str(dims(1))//' '// &
                   str(dims(2))//' '//str(dims(3)))
      return
    end if
    n_ranks = product(int(dims, i8))
    if (n_ranks > huge(1)) then
      call err%set(ERR_INPUT, 'domain: dims give more than 2^31 ranks')
      return
    end if
    if (rank < 0 .or. rank >= n_ranks) then
      call err%set(ERR_INPUT, 'domain: rank '//str(rank)//' is not in 0..'//str(n_ranks - 1))
      return
    end if
    self%h = box_size
    self%inv_h = 1.0_dp/box_size
    ! 2^54 h without overflowing: beyond it a point is far outside the global box anyway
    ! (|bounds| <= 2^52 boxes), and point*inv_h could overflow (a trap in Debug builds)
    if (box_size >= huge(1.0_dp)*2.0_dp**(-54)) then
      self%point_limit = huge(1.0_dp)
    else
      self%point_limit = box_size*2.0_dp**54
    end if
    ! the same arithmetic as cell_grid's placement: floor(x*inv_h)
    self%global%lo = int(floor(lower*self%inv_h), i8)
    self%global%hi = int(floor(upper*self%inv_h), i8)
    self%n_boxes = self%global%hi - self%global%lo + 1
    do d = 1, 3
      if (dims(d) > 1 .and. self%n_boxes(d) < 2_i8*dims(d)) then
        call err%set(ERR_INPUT, 'domain: along '//AXIS_NAME(d)//' the scene spans '//str(self%n_boxes(d))// &
                     ' grid box(es) of '//str(box_size, '(es10.3)')//' m, too few for '//str(dims(d))// &
                     ' ranks: each rank needs at least two whole boxes ('//str(2_i8*dims(d))// &
                     ' in all); use fewer ranks along '//AXIS_NAME(d)//' or a smaller grid box')
        return
      end if
    end do
    self%dims = dims
    self%n_ranks = int(n_ranks)
    self%rank = rank
    self%coords = self%coords_of(rank)
    self%own = self%brick(rank)
  end subroutine domain_init

  !> 0-based Cartesian coordinates of a rank (MPI_Cart_coords, row-major).
  pure function domain_coords_of(self, rank) result(c)
    class(domain_t), intent(in) :: self
    integer, intent(in) :: rank
    integer :: c(3)
    c(3) = mod(rank, self%dims(3))
    c(2) = mod(rank/self%dims(3), self%dims(2))
    c(1) = rank/(self%dims(3)*self%dims(2))
  end function domain_coords_of

  !> The rank at coordinates c, NO_RANK outside the rank grid (no periodicity).
  pure integer function domain_rank_of(self, c) result(rank)
    class(domain_t), intent(in) :: self
    integer, intent(in) :: c(3)
    if (any(c < 0) .or. any(c >= self%dims)) then
      rank = NO_RANK
    else
      rank = (c(1)*self%dims(2) + c(2))*self%dims(3) + c(3)
    end if
  end function domain_rank_of

  !> The boxes of a rank's brick.
  pure type(box_range_t) function domain_brick(self, rank) result(b)
    class(domain_t), intent(in) :: self
    integer, intent(in) :: rank
    integer :: c(3), d
    c = self%coords_of(rank)
    do d = 1, 3
      b%lo(d) = self%global%lo(d) + (self%n_boxes(d)*c(d))/self%dims(d)
      b%hi(d) = self%global%lo(d) + (self%n_boxes(d)*(c(d) + 1))/self%dims(d) - 1
    end do
  end function domain_brick

  !> The grid box holding a point [m], clamped to the global box (finite points only).
  pure function domain_box_of(self, point) result(k)
    class(domain_t), intent(in) :: self
    real(dp), intent(in) :: point(3)
    integer(i8) :: k(3)
    real(dp) :: t(3)
    ! clamp in reals first: a point far outside must not overflow the integer conversion,
    ! nor (huge coordinates) the scaling; inside the limit the arithmetic is cell_grid's
    t = min(max(point, -self%point_limit), self%point_limit)*self%inv_h
    t = min(max(t, real(self%global%lo, dp)), real(self%global%hi, dp))
    k = int(floor(t), i8)
  end function domain_box_of

  !> The rank whose brick holds grid box k (k inside the global box).
  pure integer function domain_owner_of_box(self, k) result(rank)
    class(domain_t), intent(in) :: self
    integer(i8), intent(in) :: k(3)
    integer :: c(3), d
    integer(i8) :: j
    do d = 1, 3
      ! the inverse of the brick's first box lo + floor(n c/p): the largest c with
      ! floor(n c/p) <= j is floor((p (j+1) - 1)/n)
      j = min(max(k(d), self%global%lo(d)), self%global%hi(d)) - self%global%lo(d)
      c(d) = int((int(self%dims(d), i8)*(j + 1) - 1)/self%n_boxes(d))
    end do
    rank = self%rank_of(c)
  end function domain_owner_of_box

  !> The rank owning the brick that holds a point [m] (a body's centre of mass): the upper
  !> brick on a face, the edge bricks outside the global box; NO_RANK for NaN.
  pure integer function domain_owner_of(self, point) result(rank)
    class(domain_t), intent(in) :: self
    real(dp), intent(in) :: point(3)
    if (any(ieee_is_nan(point))) then
      rank = NO_RANK
      return
    end if
    rank = self%owner_of_box(self%box_of(point))
  end function domain_owner_of

  !> The face neighbour of this rank in a direction (MINUS_X .. PLUS_Z), NO_RANK at the
  !> edge of the rank grid (MPI_Cart_shift(axis - 1, side)).
  pure integer function domain_face_neighbour(self, direction) result(rank)
    class(domain_t), intent(in) :: self
    integer, intent(in) :: direction
    integer :: c(3), a
    a = direction_axis(direction)
    c = self%coords
    c(a) = c(a) + direction_side(direction)
    rank = self%rank_of(c)
  end function domain_face_neighbour

  !> The up-to-26 ranks whose bricks touch this one (faces, edges, corners), ascending.
  pure function domain_neighbours(self) result(ranks)
    class(domain_t), intent(in) :: self
    integer, allocatable :: ranks(:)
    integer :: buffer(26), n, i, j, k, r
    n = 0
    ! coordinates in row-major order give ascending ranks
    do i = -1, 1
      do j = -1, 1
        do k = -1, 1
          if (i == 0 .and. j == 0 .and. k == 0) cycle
          r = self%rank_of(self%coords + [i, j, k])
          if (r == NO_RANK) cycle
          n = n + 1
          buffer(n) = r
        end do
      end do
    end do
    ranks = buffer(1:n)
  end function domain_neighbours

  !> The brick grown by `rings` boxes on every side, inside the global box: brick + halo.
  pure type(box_range_t) function domain_halo_region(self, rings) result(b)
    class(domain_t), intent(in) :: self
    integer, intent(in) :: rings
    integer :: r
    r = clamp_rings(rings)
    b%lo = max(self%own%lo - r, self%global%lo)
    b%hi = min(self%own%hi + r, self%global%hi)
  end function domain_halo_region

  !> Whether a point [m] lies in this rank's halo of `rings` rings: its (clamped) box is
  !> within `rings` boxes of the brick along every axis but not in the brick.
  pure logical function domain_in_halo(self, point, rings) result(inside)
    class(domain_t), intent(in) :: self
    real(dp), intent(in) :: point(3)
    integer, intent(in) :: rings
    integer(i8) :: k(3)
    type(box_range_t) :: region
    inside = .false.
    if (any(ieee_is_nan(point))) return
    k = self%box_of(point)
    region = self%halo_region(rings)
    inside = region%holds(k) .and. .not. self%own%holds(k)
  end function domain_in_halo

  !> The boxes this rank sends to its face neighbour in `direction` during the staged
  !> exchange of `rings` rings (empty without a neighbour there): the `rings` outer layers
  !> of the brick on that side; along the axes exchanged before (x before y before z) the
  !> brick grown by the halo received in those passes, so edges and corners are forwarded;
  !> along the later axes the brick alone. Needs rings <= the brick's width along the axis,
  !> which the two-boxes-per-rank rule guarantees.
  pure type(box_range_t) function domain_halo_send_boxes(self, direction, rings) result(b)
    class(domain_t), intent(in) :: self
    integer, intent(in) :: direction, rings
    integer :: a, r
    type(box_range_t) :: region
    if (self%face_neighbour(direction) == NO_RANK) return   ! b empty
    a = direction_axis(direction)
    r = clamp_rings(rings)
    region = self%halo_region(r)
    b = self%own
    b%lo(1:a - 1) = region%lo(1:a - 1)
    b%hi(1:a - 1) = region%hi(1:a - 1)
    if (direction_side(direction) > 0) then
      b%lo(a) = self%own%hi(a) - r + 1
    else
      b%hi(a) = self%own%lo(a) + r - 1
    end if
  end function domain_halo_send_boxes

  !> Dims for n ranks like MPI_Dims_create: entries of fixed > 0 are kept, the free ones
  !> (0) get factors of n/(product of the fixed) as close to each other as possible (the
  !> smallest largest factor, then the largest smallest), in non-increasing order. With
  !> n_boxes (the scene's boxes per axis) the free factors go instead to the free axes in
  !> decreasing order of their box counts (ties: x before y before z), so a long scene is
  !> cut across its length.
  subroutine suggest_dims(n, fixed, dims, err, n_boxes)
    integer, intent(in) :: n
    integer, intent(in) :: fixed(3)
    integer, intent(out) :: dims(3)
    type(error_t), intent(inout) :: err
    integer(i8), intent(in), optional :: n_boxes(3)
    integer :: m, n_free, f1, f2, f3, d, k, slot(3), best(3), trial(3), tmp
    integer(i8) :: fixed_product
    dims = 1
    if (n < 1) then
      call err%set(ERR_INPUT, 'domain: the number of ranks must be >= 1, not '//str(n))
      return
    end if
    if (any(fixed < 0)) then
      call err%set(ERR_INPUT, 'domain: dims entries must be >= 0 (0: free), not '//str(fixed(1))//' '// &
                   str(fixed(2))//' '//str(fixed(3)))
      return
    end if
    fixed_product = product(int(max(fixed, 1), i8))
    if (mod(int(n, i8), fixed_product) /= 0) then
      call err%set(ERR_INPUT, 'domain: dims = '//str(fixed(1))//' '//str(fixed(2))//' '//str(fixed(3))// &
                   ' fix '//str(fixed_product)//' ranks, which do not divide the '//str(n)//' ranks of the run')
      return
    end if
    m = int(n/fixed_product)
    n_free = count(fixed == 0)
    if (n_free == 0) then
      if (m /= 1) then
        call err%set(ERR_INPUT, 'domain: dims = '//str(fixed(1))//' '//str(fixed(2))//' '//str(fixed(3))// &
                     ' make '//str(fixed_product)//' ranks, not the '//str(n)//' ranks of the run')
        return
      end if
      dims = fixed
      return
    end if
    ! every ordered factorisation f1 >= f2 >= f3 of m over the free entries (divisor
    ! loops: n is a rank count, small enough)
    best = [m, 1, 1]
    do f1 = 1, m
      if (mod(m, f1) /= 0) cycle
      do f2 = 1, f1
        if (mod(m/f1, f2) /= 0) cycle
        f3 = m/f1/f2
        if (f3 > f2) cycle
        if (n_free == 1 .and. (f2 /= 1 .or. f3 /= 1)) cycle
        if (n_free == 2 .and. f3 /= 1) cycle
        trial = [f1, f2, f3]
        if (better(trial, best, n_free)) best = trial
      end do
    end do
    ! the free axes, in the order their factors are handed out
    k = 0
    do d = 1, 3
      if (fixed(d) == 0) then
        k = k + 1
        slot(k) = d
      end if
    end do
    if (present(n_boxes)) then
      ! stable insertion sort of the free axes by decreasing box count
      do d = 2, n_free
        tmp = slot(d)
        k = d - 1
        do while (k >= 1)
          if (n_boxes(slot(k)) >= n_boxes(tmp)) exit
          slot(k + 1) = slot(k)
          k = k - 1
        end do
        slot(k + 1) = tmp
      end do
    end if
    dims = fixed
    do k = 1, n_free
      dims(slot(k)) = best(k)
    end do
  contains
    pure logical function better(a, b, nf)
      integer, intent(in) :: a(3), b(3), nf
      ! balanced: the smallest largest factor, then the largest smallest one
      if (a(1) /= b(1)) then
        better = a(1) < b(1)
      else
        better = a(nf) > b(nf)
      end if
    end function better
  end subroutine suggest_dims

  pure integer function direction_axis(direction)
    integer, intent(in) :: direction
    direction_axis = (direction + 1)/2
  end function direction_axis

  !> -1 towards lower coordinates, +1 towards higher.
  pure integer function direction_side(direction)
    integer, intent(in) :: direction
    direction_side = merge(-1, 1, mod(direction, 2) == 1)
  end function direction_side

  pure integer function clamp_rings(rings)
    integer, intent(in) :: rings
    clamp_rings = min(max(rings, 0), MAX_HALO_RINGS)
  end function clamp_rings

  pure logical function range_is_empty(self)
    class(box_range_t), intent(in) :: self
    range_is_empty = any(self%hi < self%lo)
  end function range_is_empty

  pure integer(i8) function range_n_boxes(self)
    class(box_range_t), intent(in) :: self
    range_n_boxes = product(max(self%hi - self%lo + 1, 0_i8))
  end function range_n_boxes

  pure logical function range_holds(self, k)
    class(box_range_t), intent(in) :: self
    integer(i8), intent(in) :: k(3)
    range_holds = all(k >= self%lo .and. k <= self%hi)
  end function range_holds

end module domain
