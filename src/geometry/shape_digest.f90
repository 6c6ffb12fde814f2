!> A shape's geometry as one number (src/common/digest.f90): a sphere's radius, or the nodes
!> and faces of a mesh as read, welded and scaled (before the turn into the principal
!> frame, whose last bits depend on how the eigensolver was compiled). A checkpoint stores
!> it per shape, so a restart notices a swapped mesh file, a changed scale or a cube
!> replaced by a sphere of the same mass.
module shape_digest
  use kinds, only: dp, i8
  use digest, only: digest_t
  use mesh, only: mesh_t
  implicit none
  private
  public :: mesh_digest, sphere_digest

contains

  pure integer(i8) function mesh_digest(m) result(value)
    type(mesh_t), intent(in) :: m
    type(digest_t) :: d
    integer :: k
    call d%add_int(2)
    call d%add_int(m%n_nodes)
    call d%add_int(m%n_faces)
    do k = 1, m%n_nodes
      call d%add_reals(m%nodes(:, k))
    end do
    do k = 1, m%n_faces
      call d%add_ints(m%faces(:, k))
    end do
    value = d%value()
  end function mesh_digest

  pure integer(i8) function sphere_digest(radius) result(value)
    real(dp), intent(in) :: radius
    type(digest_t) :: d
    call d%add_int(1)
    call d%add_real(radius)
    value = d%value()
  end function sphere_digest

end module shape_digest
