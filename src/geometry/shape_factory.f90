!> Builds shape_t values: analytic spheres, and mesh shapes moved into their principal
!> frame (centre of mass at the origin, principal axes along x, y, z, moments ascending).
module shape_factory
  use kinds, only: dp
  use constants, only: pi
  use mesh, only: mesh_t
  use shape, only: shape_t, SHAPE_SPHERE, SHAPE_MESH
  use error_status, only: error_t
  use shape_digest, only: mesh_digest, sphere_digest
  use mass_properties, only: polyhedron_mass_properties
  use linear_algebra, only: symmetric_eigen
  use quaternion, only: quat_from_matrix, quat_to_matrix, quat_identity
  use string_utils, only: str
  implicit none
  private
  public :: make_sphere_shape, make_mesh_shape

contains

  !> Analytic sphere of the given radius [m] (> 0, checked by the caller): exact volume
  !> and inertia, no mesh.
  subroutine make_sphere_shape(radius, s)
    real(dp), intent(in) :: radius
    type(shape_t), intent(out) :: s
    s%kind = SHAPE_SPHERE
    s%label = 'sphere r='//str(radius)
    s%radius = radius
    s%digest = sphere_digest(radius)
    s%volume = 4.0_dp/3.0_dp*pi*radius**3
    ! Solid sphere: I = 2/5 M r^2 about any axis through the centre; per unit density M = V.
    s%unit_inertia = 0.4_dp*radius**2*s%volume
    s%q_principal = quat_identity
    s%com_offset = 0.0_dp
    s%bounding_radius = radius
    s%aabb_lower = -radius
    s%aabb_upper = radius
  end subroutine make_sphere_shape

  !> Mesh shape from a closed outward mesh m given in the shape's own (definition) frame.
  !> Stores the volume, the principal moments (ascending) per unit density, the centre of
  !> mass com_offset and the principal frame q_principal (p_definition = com_offset +
  !> R(q_principal) p_principal) and the mesh moved into the principal frame, with its
  !> bounding radius about the centre of mass and its bounds there. m's topology arrays,
  !> if any, are kept as they are (a rigid motion does not change them).
  subroutine make_mesh_shape(m, label, s, err)
    type(mesh_t), intent(in) :: m
    character(len=*), intent(in) :: label
    type(shape_t), intent(out) :: s
    type(error_t), intent(out) :: err
    real(dp) :: volume, centroid(3), inertia(3, 3), moments(3), axes(3, 3), rotation(3, 3)
    integer :: i

    s%digest = mesh_digest(m)
    call polyhedron_mass_properties(m, volume, centroid, inertia, err)
    if (err%failed()) then
      call err%prefix('shape '''//label//''': ')
      return
    end if
    call symmetric_eigen(inertia, moments, axes, err)
    if (err%failed()) then
      call err%prefix('shape '''//label//''', principal axes: ')
      return
    end if

    s%kind = SHAPE_MESH
    s%label = label
    s%volume = volume
    s%unit_inertia = moments
    s%com_offset = centroid
    s%q_principal = quat_from_matrix(axes)
    ! Move the mesh with the rotation of the stored quaternion itself (not axes, which can
    ! differ from it by round-off) so that mesh and q_principal agree exactly.
    rotation = transpose(quat_to_matrix(s%q_principal))
    s%mesh = m
    call s%mesh%transform(rotation, centroid)
    s%bounding_radius = 0.0_dp
    do i = 1, s%mesh%n_nodes
      s%bounding_radius = max(s%bounding_radius, norm2(s%mesh%nodes(:, i)))
    end do
    call s%mesh%bounds(s%aabb_lower, s%aabb_upper)
  end subroutine make_mesh_shape

end module shape_factory
