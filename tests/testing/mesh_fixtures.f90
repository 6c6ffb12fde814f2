!> Small closed meshes for geometry tests and benchmarks (outward, counter-clockwise faces):
!> boxes and plates, icospheres, tori, extruded L-prisms, star-shaped blobs. Test-only
!> stand-ins for the library's shape_builders, so geometry tests do not depend on them.
module mesh_fixtures
  use, intrinsic :: iso_fortran_env, only: dp => real64
  use mesh, only: mesh_t
  implicit none
  private
  public :: box_fixture, icosphere_fixture, torus_fixture, l_prism_fixture, blob_fixture, &
            random_unit_quaternion, random_unit_vector, axis_angle_quaternion

contains

  !> Box with half extents h [m], centred at the origin (12 faces).
  subroutine box_fixture(h, m)
    real(dp), intent(in) :: h(3)
    type(mesh_t), intent(out) :: m
    real(dp) :: nodes(3, 8)
    integer :: i
    ! node i has bits (x, y, z) = bits of i - 1: 0 -> -h, 1 -> +h
    do i = 1, 8
      nodes(1, i) = merge(h(1), -h(1), btest(i - 1, 0))
      nodes(2, i) = merge(h(2), -h(2), btest(i - 1, 1))
      nodes(3, i) = merge(h(3), -h(3), btest(i - 1, 2))
    end do
    call m%init(nodes, reshape([1, 3, 4, 1, 4, 2, &     ! z = -h: normal -z
                                5, 6, 8, 5, 8, 7, &     ! z = +h
                                1, 2, 6, 1, 6, 5, &     ! y = -h
                                3, 7, 8, 3, 8, 4, &     ! y = +h
                                1, 5, 7, 1, 7, 3, &     ! x = -h
                                2, 4, 8, 2, 8, 6], [3, 12]), 'box fixture')
  end subroutine box_fixture

  !> Icosphere of radius r [m]: icosahedron subdivided `level` times (20 * 4**level faces).
  subroutine icosphere_fixture(r, level, m)
    real(dp), intent(in) :: r
    integer, intent(in) :: level
    type(mesh_t), intent(out) :: m
    real(dp), allocatable :: nodes(:, :)
    integer, allocatable :: faces(:, :), next(:, :), adj(:, :), nadj(:)
    real(dp) :: t
    integer :: nn, nf, l, f, k, a(3), mid(3), n_max
    t = (1.0_dp + sqrt(5.0_dp))/2.0_dp
    n_max = 10*4**level + 2
    allocate (nodes(3, n_max))
    nodes(:, 1:12) = reshape([-1.0_dp, t, 0.0_dp, 1.0_dp, t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp, -t, 0.0_dp, &
                              0.0_dp, -1.0_dp, t, 0.0_dp, 1.0_dp, t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp, -t, &
                              t, 0.0_dp, -1.0_dp, t, 0.0_dp, 1.0_dp, -t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp], [3, 12])
    faces = standard_icosahedron_faces()
    nn = 12
    nf = 20
    do k = 1, nn
      nodes(:, k) = nodes(:, k)/norm2(nodes(:, k))
    end do
    allocate (adj(2, 0), nadj(0))
    do l = 1, level
      deallocate (adj, nadj)
      allocate (adj(2*8, n_max), nadj(n_max))
      nadj = 0
      allocate (next(3, 4*nf))
      do f = 1, nf
        a = faces(:, f)
        do k = 1, 3
          mid(k) = midpoint(a(k), a(mod(k, 3) + 1))
        end do
        next(:, 4*f - 3) = [a(1), mid(1), mid(3)]
        next(:, 4*f - 2) = [a(2), mid(2), mid(1)]
        next(:, 4*f - 1) = [a(3), mid(3), mid(2)]
        next(:, 4*f) = [mid(1), mid(2), mid(3)]
      end do
      nf = 4*nf
      call move_alloc(next, faces)
    end do
    call m%init(r*nodes(:, 1:nn), faces(:, 1:nf), 'icosphere fixture')
  contains
    integer function midpoint(i, j)
      integer, intent(in) :: i, j
      integer :: lo, hi, s
      lo = min(i, j)
      hi = max(i, j)
      do s = 1, nadj(lo)
        if (adj(2*s - 1, lo) == hi) then
          midpoint = adj(2*s, lo)
          return
        end if
      end do
      nn = nn + 1
      nodes(:, nn) = nodes(:, i) + nodes(:, j)
      nodes(:, nn) = nodes(:, nn)/norm2(nodes(:, nn))
      nadj(lo) = nadj(lo) + 1
      adj(2*nadj(lo) - 1, lo) = hi
      adj(2*nadj(lo), lo) = nn
      midpoint = nn
    end function midpoint
  end subroutine icosphere_fixture

  pure function standard_icosahedron_faces() result(f)
    integer :: f(3, 20)
    f = reshape([1, 12, 6, 1, 6, 2, 1, 2, 8, 1, 8, 11, 1, 11, 12, &
                 2, 6, 10, 6, 12, 5, 12, 11, 3, 11, 8, 7, 8, 2, 9, &
                 4, 10, 5, 4, 5, 3, 4, 3, 7, 4, 7, 9, 4, 9, 10, &
                 5, 10, 6, 3, 5, 12, 7, 3, 11, 9, 7, 8, 10, 9, 2], [3, 20])
  end function standard_icosahedron_faces

  !> Torus about z: major radius big_r, minor radius small_r [m], nu x nv quads (2 nu nv faces).
  subroutine torus_fixture(big_r, small_r, nu, nv, m)
    real(dp), intent(in) :: big_r, small_r
    integer, intent(in) :: nu, nv
    type(mesh_t), intent(out) :: m
    real(dp), allocatable :: nodes(:, :)
    integer, allocatable :: faces(:, :)
    real(dp) :: u, v, pi
    integer :: i, j, a, b, c, d, f
    pi = 4.0_dp*atan(1.0_dp)
    allocate (nodes(3, nu*nv), faces(3, 2*nu*nv))
    do i = 0, nu - 1
      u = 2.0_dp*pi*i/nu
      do j = 0, nv - 1
        v = 2.0_dp*pi*j/nv
        nodes(:, i*nv + j + 1) = [(big_r + small_r*cos(v))*cos(u), (big_r + small_r*cos(v))*sin(u), small_r*sin(v)]
      end do
    end do
    f = 0
    do i = 0, nu - 1
      do j = 0, nv - 1
        a = i*nv + j + 1
        b = mod(i + 1, nu)*nv + j + 1
        c = mod(i + 1, nu)*nv + mod(j + 1, nv) + 1
        d = i*nv + mod(j + 1, nv) + 1
        faces(:, f + 1) = [a, b, c]
        faces(:, f + 2) = [a, c, d]
        f = f + 2
      end do
    end do
    call m%init(nodes, faces, 'torus fixture')
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
