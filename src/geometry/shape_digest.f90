!> A shape's geometry as one number (src/common/digest.f90): its kind, sphere radius, and
!> the nodes and faces of its mesh after welding, scaling and the turn into the principal
!> frame. A checkpoint stores it per shape, so a restart notices a swapped mesh file, a
!> changed scale or a cube replaced by a sphere of the same mass.
module shape_digest
  use kinds, only: i8
  use digest, only: digest_t
  use shape, only: shape_t, SHAPE_SPHERE
  implicit none
  private
  public :: geometry_digest

contains

  pure integer(i8) function geometry_digest(s) result(value)
    type(shape_t), intent(in) :: s
    type(digest_t) :: d
    integer :: k
    call d%add_int(s%kind)
    if (s%kind == SHAPE_SPHERE) then
      call d%add_real(s%radius)
    else
      call d%add_int(s%mesh%n_nodes)
      call d%add_int(s%mesh%n_faces)
      do k = 1, s%mesh%n_nodes
        call d%add_reals(s%mesh%nodes(:, k))
      end do
      do k = 1, s%mesh%n_faces
        call d%add_ints(s%mesh%faces(:, k))
      end do
    end if
    value = d%value()
  end function geometry_digest

end module shape_digest
