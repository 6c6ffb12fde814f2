!> A rigid shape: geometry and mass properties per unit density, stored in its principal
!> frame with the centre of mass at the origin. Shapes are shared: every copy of a body
!> (a lattice of 10,000 cubes) points at one shape_t through its shape index.
module shape
  use kinds, only: dp, i8
  use mesh, only: mesh_t
  use skd_tree, only: skd_tree_t
  use quaternion, only: quat_identity
  implicit none
  private
  public :: shape_t, shape_library_t, SHAPE_SPHERE, SHAPE_MESH

  integer, parameter :: SHAPE_SPHERE = 1   !< analytic sphere: exact geometry and inertia
  integer, parameter :: SHAPE_MESH = 2     !< closed triangle mesh (boxes, cylinders, files)

  type :: shape_t
    integer :: kind = SHAPE_MESH
    character(len=:), allocatable :: label   !< what it was built from, e.g. "box 1 x 2 x 3 m"
    real(dp) :: radius = 0.0_dp              !< analytic sphere radius [m]
    type(mesh_t) :: mesh                     !< mesh shapes: surface in the principal frame [m]
    type(skd_tree_t) :: tree                 !< mesh shapes: SKD-tree for closest points, built once
    real(dp) :: volume = 0.0_dp              !< [m^3]
    real(dp) :: unit_inertia(3) = 0.0_dp     !< principal moments per unit density [m^5], ascending
    !> Orientation of the principal frame in the shape's own (definition) frame: a point p
    !> in the principal frame is com_offset + R(q_principal) p in the definition frame.
    real(dp) :: q_principal(4) = quat_identity
    real(dp) :: com_offset(3) = 0.0_dp       !< centre of mass in the definition frame [m]
    real(dp) :: bounding_radius = 0.0_dp     !< largest distance of the surface from the COM [m]
    logical :: convex = .true.               !< convex solid (spheres, boxes, ...): tighter contact bounds
    real(dp) :: aabb_lower(3) = 0.0_dp       !< bounds in the principal frame [m]
    real(dp) :: aabb_upper(3) = 0.0_dp
    !> Digest of the geometry it was built from (shape_digest): restarts compare it
    integer(i8) :: digest = 0
  end type shape_t

  !> All distinct shapes of a run. Bodies refer to them by index.
  type :: shape_library_t
    integer :: n_shapes = 0
    type(shape_t), allocatable :: shapes(:)
  contains
    procedure :: add => library_add
    procedure :: find => library_find
    procedure :: free => library_free
  end type shape_library_t

contains

  !> Appends a shape and returns its index.
  subroutine library_add(self, new_shape, index)
    class(shape_library_t), intent(inout) :: self
    type(shape_t), intent(in) :: new_shape
    integer, intent(out) :: index
    type(shape_t), allocatable :: grown(:)
    integer :: i
    if (.not. allocated(self%shapes)) allocate (self%shapes(4))
    if (self%n_shapes == size(self%shapes)) then
      allocate (grown(2*size(self%shapes)))
      do i = 1, self%n_shapes
        grown(i) = self%shapes(i)
      end do
      call move_alloc(grown, self%shapes)
    end if
    self%n_shapes = self%n_shapes + 1
    self%shapes(self%n_shapes) = new_shape
    index = self%n_shapes
  end subroutine library_add

  !> Index of the shape with this label, 0 if none: shapes built from the same
  !> description are built once.
  pure integer function library_find(self, label)
    class(shape_library_t), intent(in) :: self
    character(len=*), intent(in) :: label
    integer :: i
    library_find = 0
    do i = 1, self%n_shapes
      if (self%shapes(i)%label == label) then
        library_find = i
        return
      end if
    end do
  end function library_find

  subroutine library_free(self)
    class(shape_library_t), intent(inout) :: self
    if (allocated(self%shapes)) deallocate (self%shapes)
    self%n_shapes = 0
  end subroutine library_free

end module shape
