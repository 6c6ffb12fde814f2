!> Small closed meshes for geometry tests and benchmarks (outward, counter-clockwise faces):
!> boxes and plates, icospheres, tori (the library's shape_builders), and the test-only
!> extruded L-prism with its inner corner at a known place and star-shaped blobs.
module mesh_fixtures
  use, intrinsic :: iso_fortran_env, only: dp => real64
  use mesh, only: mesh_t
  use shape_builders, only: box_mesh, icosphere_mesh, torus_mesh
  implicit none
  private
  public :: box_fixture, icosphere_fixture, torus_fixture, l_prism_fixture, blob_fixture, &
            random_unit_quaternion, random_unit_vector, axis_angle_quaternion

contains

  !> Box with half extents h [m], centred at the origin (12 faces): the library's box.
  subroutine box_fixture(h, m)
    real(dp), intent(in) :: h(3)
    type(mesh_t), intent(out) :: m
    call box_mesh(2.0_dp*h, m)
  end subroutine box_fixture

  !> Icosphere of radius r [m]: icosahedron subdivided `level` times (20 * 4**level faces).
  subroutine icosphere_fixture(r, level, m)
    real(dp), intent(in) :: r
    integer, intent(in) :: level
    type(mesh_t), intent(out) :: m
    call icosphere_mesh(r, level, m)
  end subroutine icosphere_fixture


  !> Torus about z: major radius big_r, minor radius small_r [m], nu x nv quads (2 nu nv faces).
  subroutine torus_fixture(big_r, small_r, nu, nv, m)
    real(dp), intent(in) :: big_r, small_r
    integer, intent(in) :: nu, nv
    type(mesh_t), intent(out) :: m
    call torus_mesh(big_r, small_r, nu, nv, m)
  end subroutine torus_fixture

  !> L-shaped prism: the polygon (0,0) (2,0) (2,1) (1,1) (1,2) (0,2) times w [m] in x and y,
  !> extruded from z = 0 to z = height [m] (20 faces). The inner corner is at (w, w).
  subroutine l_prism_fixture(w, height, m)
    real(dp), intent(in) :: w, height
    type(mesh_t), intent(out) :: m
    real(dp) :: poly(2, 6), nodes(3, 12)
    integer :: faces(3, 20), i, j, f
    ! fan from the reflex vertex 4 = (1,1): every triangle counter-clockwise seen from +z
    integer, parameter :: cap(3, 4) = reshape([4, 5, 6, 4, 6, 1, 4, 1, 2, 4, 2, 3], [3, 4])
    poly = w*reshape([0.0_dp, 0.0_dp, 2.0_dp, 0.0_dp, 2.0_dp, 1.0_dp, 1.0_dp, 1.0_dp, 1.0_dp, 2.0_dp, &
                      0.0_dp, 2.0_dp], [2, 6])
    do i = 1, 6
      nodes(:, i) = [poly(:, i), 0.0_dp]
      nodes(:, i + 6) = [poly(:, i), height]
    end do
    f = 0
    do i = 1, 4
      faces(:, f + 1) = cap(:, i) + 6             ! top, normal +z
      faces(:, f + 2) = [cap(1, i), cap(3, i), cap(2, i)]   ! bottom, normal -z
      f = f + 2
    end do
    do i = 1, 6
      j = mod(i, 6) + 1
      faces(:, f + 1) = [i, j, j + 6]
      faces(:, f + 2) = [i, j + 6, i + 6]
      f = f + 2
    end do
    call m%init(nodes, faces, 'L-prism fixture')
  end subroutine l_prism_fixture

  !> Star-shaped, non-convex blob: an icosphere whose node radii vary smoothly with
  !> direction, r(u) = r0 (1 + a sin(3 u1 + p1) cos(2 u2 + p2) + a/2 sin(4 u3 + p3)).
  subroutine blob_fixture(r0, level, amplitude, phases, m)
    real(dp), intent(in) :: r0, amplitude, phases(3)
    integer, intent(in) :: level
    type(mesh_t), intent(out) :: m
    integer :: i
    real(dp) :: u(3)
    call icosphere_fixture(1.0_dp, level, m)
    do i = 1, m%n_nodes
      u = m%nodes(:, i)
      m%nodes(:, i) = r0*u*(1.0_dp + amplitude*sin(3.0_dp*u(1) + phases(1))*cos(2.0_dp*u(2) + phases(2)) &
                            + 0.5_dp*amplitude*sin(4.0_dp*u(3) + phases(3)))
    end do
    m%source = 'blob fixture'
  end subroutine blob_fixture

  !> Uniformly random rotation (Shoemake's method) from random_number.
  function random_unit_quaternion() result(q)
    real(dp) :: q(4), u(3), pi
    pi = 4.0_dp*atan(1.0_dp)
    call random_number(u)
    q = [sqrt(1.0_dp - u(1))*sin(2.0_dp*pi*u(2)), sqrt(1.0_dp - u(1))*cos(2.0_dp*pi*u(2)), &
         sqrt(u(1))*sin(2.0_dp*pi*u(3)), sqrt(u(1))*cos(2.0_dp*pi*u(3))]
  end function random_unit_quaternion

  function random_unit_vector() result(v)
    real(dp) :: v(3), u(2), pi, z, r
    pi = 4.0_dp*atan(1.0_dp)
    call random_number(u)
    z = 2.0_dp*u(1) - 1.0_dp
    r = sqrt(max(0.0_dp, 1.0_dp - z*z))
    v = [r*cos(2.0_dp*pi*u(2)), r*sin(2.0_dp*pi*u(2)), z]
  end function random_unit_vector

  pure function axis_angle_quaternion(axis, angle) result(q)
    real(dp), intent(in) :: axis(3), angle
    real(dp) :: q(4)
    q = [cos(0.5_dp*angle), sin(0.5_dp*angle)*axis/norm2(axis)]
  end function axis_angle_quaternion

end module mesh_fixtures
