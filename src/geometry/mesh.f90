!> Closed triangle surface mesh: nodes, faces (counter-clockwise seen from outside, so
!> the right-hand normal points out) and, once the topology is built, the unique edges with
!> the two faces that share each one. Readers (mesh_io) and builders (shape_builders) make
!> one; mesh_topology checks it is closed, manifold and consistently oriented.
module mesh
  use kinds, only: dp
  use vector_ops, only: cross
  implicit none
  private
  public :: mesh_t

  type :: mesh_t
    integer :: n_nodes = 0
    integer :: n_faces = 0
    integer :: n_edges = 0
    real(dp), allocatable :: nodes(:, :)       !< (3, n_nodes) [m]
    integer, allocatable :: faces(:, :)        !< (3, n_faces) node indices, outward CCW
    integer, allocatable :: edges(:, :)        !< (2, n_edges) node indices, edges(1,e) < edges(2,e)
    integer, allocatable :: edge_faces(:, :)   !< (2, n_edges) the two faces sharing edge e
    integer, allocatable :: face_edges(:, :)   !< (3, n_faces) face_edges(k,f) joins face nodes k and mod(k,3)+1
    character(len=:), allocatable :: source    !< file name or built-in description, for messages
  contains
    procedure :: init => mesh_init
    procedure :: free => mesh_free
    procedure :: face_normal => mesh_face_normal
    procedure :: face_area => mesh_face_area
    procedure :: transform => mesh_transform
    procedure :: bounds => mesh_bounds
    procedure :: has_topology => mesh_has_topology
  end type mesh_t

contains

  !> Takes nodes and faces; topology (edges) is built separately by mesh_topology.
  subroutine mesh_init(self, nodes, faces, source)
    class(mesh_t), intent(inout) :: self
    real(dp), intent(in) :: nodes(:, :)
    integer, intent(in) :: faces(:, :)
    character(len=*), intent(in) :: source
    call self%free()
    self%n_nodes = size(nodes, 2)
    self%n_faces = size(faces, 2)
    self%nodes = nodes
    self%faces = faces
    self%source = source
  end subroutine mesh_init

  subroutine mesh_free(self)
    class(mesh_t), intent(inout) :: self
    if (allocated(self%nodes)) deallocate (self%nodes)
    if (allocated(self%faces)) deallocate (self%faces)
    if (allocated(self%edges)) deallocate (self%edges)
    if (allocated(self%edge_faces)) deallocate (self%edge_faces)
    if (allocated(self%face_edges)) deallocate (self%face_edges)
    if (allocated(self%source)) deallocate (self%source)
    self%n_nodes = 0
    self%n_faces = 0
    self%n_edges = 0
  end subroutine mesh_free

  pure logical function mesh_has_topology(self)
    class(mesh_t), intent(in) :: self
    mesh_has_topology = allocated(self%edges) .and. self%n_edges > 0
  end function mesh_has_topology

  !> Unit outward normal of face f (zero vector for a degenerate face).
  pure function mesh_face_normal(self, f) result(n)
    class(mesh_t), intent(in) :: self
    integer, intent(in) :: f
    real(dp) :: n(3), length
    n = cross(self%nodes(:, self%faces(2, f)) - self%nodes(:, self%faces(1, f)), &
              self%nodes(:, self%faces(3, f)) - self%nodes(:, self%faces(1, f)))
    length = norm2(n)
    if (length > 0.0_dp) n = n/length
  end function mesh_face_normal

  pure real(dp) function mesh_face_area(self, f)
    class(mesh_t), intent(in) :: self
    integer, intent(in) :: f
    mesh_face_area = 0.5_dp*norm2(cross(self%nodes(:, self%faces(2, f)) - self%nodes(:, self%faces(1, f)), &
                                        self%nodes(:, self%faces(3, f)) - self%nodes(:, self%faces(1, f))))
  end function mesh_face_area

  !> x <- rotation (x - origin): moves the mesh into a frame centred at origin with axes
  !> given by the rows of rotation.
  subroutine mesh_transform(self, rotation, origin)
    class(mesh_t), intent(inout) :: self
    real(dp), intent(in) :: rotation(3, 3), origin(3)
    integer :: i
    do i = 1, self%n_nodes
      self%nodes(:, i) = matmul(rotation, self%nodes(:, i) - origin)
    end do
  end subroutine mesh_transform

  pure subroutine mesh_bounds(self, lower, upper)
    class(mesh_t), intent(in) :: self
    real(dp), intent(out) :: lower(3), upper(3)
    lower = minval(self%nodes(:, 1:self%n_nodes), dim=2)
    upper = maxval(self%nodes(:, 1:self%n_nodes), dim=2)
  end subroutine mesh_bounds

end module mesh
