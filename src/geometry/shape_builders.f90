!> Built-in closed triangle meshes: box, cylinder, icosahedron, icosphere, tetrahedron,
!> torus, L-prism and a star-shaped random blob. Every builder returns a closed,
!> outward-oriented mesh (faces counter-clockwise seen from outside) with m%source set to
!> a description of what was built; topology (edges) is left to mesh_topology.
!>
!> Arguments are checked: an invalid one (a non-positive length, too few segments) gives
!> an empty mesh whose source says what is wrong, which make_mesh_shape and
!> polyhedron_mass_properties then report as an error naming that description.
!> Everything is deterministic: no random_number (its sequence differs between compilers).
module shape_builders
  use kinds, only: dp, i8
  use constants, only: two_pi
  use mesh, only: mesh_t
  use string_utils, only: str
  implicit none
  private
  public :: box_mesh, cylinder_mesh, icosahedron_mesh, icosphere_mesh, tetrahedron_mesh, torus_mesh, &
            l_shape_mesh, random_blob_mesh

  !> Icosphere subdivision levels allowed: level 10 already has 20 971 520 faces.
  integer, parameter :: max_icosphere_level = 10
  !> Golden ratio (1 + sqrt 5)/2.
  real(dp), parameter :: golden = 1.6180339887498948482045868343656381_dp
  !> Plane waves summed by random_blob_mesh: enough for an irregular surface, few enough
  !> to stay smooth.
  integer, parameter :: blob_waves = 8

contains

  !> Box with edge lengths size(1:3) [m] along x, y, z, centred at the origin: 8 nodes,
  !> 12 faces.
  subroutine box_mesh(size, m)
    real(dp), intent(in) :: size(3)
    type(mesh_t), intent(out) :: m
    real(dp) :: nodes(3, 8)
    integer :: i, j, k
    ! Node i + 2 j + 4 k + 1 sits at the corner (+-x, +-y, +-z) with - for 0 and + for 1.
    integer, parameter :: faces(3, 12) = reshape([ &
                                                 1, 3, 4, 1, 4, 2, &   ! z = -size(3)/2, normal -z
                                                 5, 6, 8, 5, 8, 7, &   ! z = +size(3)/2, normal +z
                                                 1, 2, 6, 1, 6, 5, &   ! y = -size(2)/2, normal -y
                                                 3, 7, 8, 3, 8, 4, &   ! y = +size(2)/2, normal +y
                                                 1, 5, 7, 1, 7, 3, &   ! x = -size(1)/2, normal -x
                                                 2, 4, 8, 2, 8, 6], [3, 12])   ! x = +size(1)/2, normal +x
    if (.not. all(size > 0.0_dp)) then
      call invalid(m, 'box_mesh: invalid size '//str(size(1))//' x '//str(size(2))//' x '//str(size(3))// &
                   ' m: every edge length must be > 0')
      return
    end if
    do k = 0, 1
      do j = 0, 1
        do i = 0, 1
          nodes(:, i + 2*j + 4*k + 1) = 0.5_dp*size*[real(2*i - 1, dp), real(2*j - 1, dp), real(2*k - 1, dp)]
        end do
      end do
    end do
    call m%init(nodes, faces, 'box '//str(size(1))//' x '//str(size(2))//' x '//str(size(3))//' m')
  end subroutine box_mesh

  !> Cylinder of radius [m] and length [m] along z, centred at the origin, with `segments`
  !> facets around. The caps are fans around a centre node, so no cap triangle is a
  !> sliver: 2 segments + 2 nodes, 4 segments faces.
  subroutine cylinder_mesh(radius, length, segments, m)
    real(dp), intent(in) :: radius, length
    integer, intent(in) :: segments
    type(mesh_t), intent(out) :: m
    real(dp), allocatable :: nodes(:, :)
    integer, allocatable :: faces(:, :)
    real(dp) :: angle
    integer :: i, inext, bottom, bottom_next, top, top_next, bottom_centre, top_centre, f

    if (.not. (radius > 0.0_dp .and. length > 0.0_dp) .or. segments < 3) then
      call invalid(m, 'cylinder_mesh: invalid radius '//str(radius)//' m, length '//str(length)// &
                   ' m or segments '//str(segments)//': lengths must be > 0 and segments >= 3')
      return
    end if
    allocate (nodes(3, 2*segments + 2), faces(3, 4*segments))
    ! Bottom ring 1..segments (z = -length/2), top ring segments+1..2 segments, then centres.
    do i = 1, segments
      angle = two_pi*real(i - 1, dp)/real(segments, dp)
      nodes(:, i) = [radius*cos(angle), radius*sin(angle), -0.5_dp*length]
      nodes(:, segments + i) = [radius*cos(angle), radius*sin(angle), 0.5_dp*length]
    end do
    bottom_centre = 2*segments + 1
    top_centre = 2*segments + 2
    nodes(:, bottom_centre) = [0.0_dp, 0.0_dp, -0.5_dp*length]
    nodes(:, top_centre) = [0.0_dp, 0.0_dp, 0.5_dp*length]
    f = 0
    do i = 1, segments
      inext = mod(i, segments) + 1
      bottom = i
      bottom_next = inext
      top = segments + i
      top_next = segments + inext
      ! Angles increase counter-clockwise seen from +z, so (tangent) x (+z) points out.
      faces(:, f + 1) = [bottom, bottom_next, top_next]
      faces(:, f + 2) = [bottom, top_next, top]
      faces(:, f + 3) = [top_centre, top, top_next]
      faces(:, f + 4) = [bottom_centre, bottom_next, bottom]
      f = f + 4
    end do
    call m%init(nodes, faces, 'cylinder r='//str(radius)//' m, length '//str(length)//' m, '// &
                str(segments)//' segments')
  end subroutine cylinder_mesh

  !> Regular icosahedron with its 12 vertices on the sphere of the given radius [m],
  !> centred at the origin: (0, +-1, +-golden) and its cyclic permutations, scaled.
  subroutine icosahedron_mesh(radius, m)
    real(dp), intent(in) :: radius
    type(mesh_t), intent(out) :: m
    real(dp) :: nodes(3, 12)
    integer :: faces(3, 20)
    if (.not. radius > 0.0_dp) then
      call invalid(m, 'icosahedron_mesh: invalid radius '//str(radius)//' m: it must be > 0')
      return
    end if
    call unit_icosahedron(nodes, faces)
    call m%init(radius*nodes, faces, 'icosahedron r='//str(radius)//' m')
  end subroutine icosahedron_mesh

  !> Icosphere: the icosahedron with every face split into 4 `level` times, new nodes at
  !> edge midpoints shared by both faces of the edge and projected onto the sphere of the
  !> given radius [m]. 10 4^level + 2 nodes, 20 4^level faces, no duplicate nodes.
  subroutine icosphere_mesh(radius, level, m)
    real(dp), intent(in) :: radius
    integer, intent(in) :: level
    type(mesh_t), intent(out) :: m
    real(dp), allocatable :: nodes(:, :)
    integer, allocatable :: faces(:, :)
    if (.not. radius > 0.0_dp .or. level < 0 .or. level > max_icosphere_level) then
      call invalid(m, 'icosphere_mesh: invalid radius '//str(radius)//' m or level '//str(level)// &
                   ': radius must be > 0 and level in 0..'//str(max_icosphere_level))
      return
    end if
    call unit_icosphere(level, nodes, faces)
    call m%init(radius*nodes, faces, 'icosphere r='//str(radius)//' m, level '//str(level))
  end subroutine icosphere_mesh

  !> Regular tetrahedron with the given edge length [m], centroid at the origin; vertices
  !> at alternate corners of a cube, (1,1,1), (1,-1,-1), (-1,1,-1), (-1,-1,1) scaled.
  subroutine tetrahedron_mesh(edge_length, m)
    real(dp), intent(in) :: edge_length
    type(mesh_t), intent(out) :: m
    real(dp), parameter :: corners(3, 4) = reshape([1.0_dp, 1.0_dp, 1.0_dp, 1.0_dp, -1.0_dp, -1.0_dp, &
                                                    -1.0_dp, 1.0_dp, -1.0_dp, -1.0_dp, -1.0_dp, 1.0_dp], [3, 4])
    ! Each face is the one opposite the missing vertex, counter-clockwise seen from outside.
    integer, parameter :: faces(3, 4) = reshape([1, 2, 3, 1, 4, 2, 1, 3, 4, 2, 4, 3], [3, 4])
    if (.not. edge_length > 0.0_dp) then
      call invalid(m, 'tetrahedron_mesh: invalid edge length '//str(edge_length)//' m: it must be > 0')
      return
    end if
    ! The corners above are 2 sqrt(2) apart.
    call m%init(edge_length/(2.0_dp*sqrt(2.0_dp))*corners, faces, &
                'tetrahedron edge '//str(edge_length)//' m')
  end subroutine tetrahedron_mesh

  !> Torus around the z axis: tube centre circle of radius major_radius [m], tube radius
  !> minor_radius [m] < major_radius, n_major segments around z and n_minor around the
  !> tube. Nodes lie on the smooth torus; every quad is a planar isosceles trapezoid.
  subroutine torus_mesh(major_radius, minor_radius, n_major, n_minor, m)
    real(dp), intent(in) :: major_radius, minor_radius
    integer, intent(in) :: n_major, n_minor
    type(mesh_t), intent(out) :: m
    real(dp), allocatable :: nodes(:, :)
    integer, allocatable :: faces(:, :)
    real(dp) :: phi, theta, rho
    integer :: i, j, inext, jnext, f, p00, p10, p11, p01

    if (.not. (minor_radius > 0.0_dp .and. major_radius > minor_radius) .or. n_major < 3 .or. n_minor < 3) then
      call invalid(m, 'torus_mesh: invalid radii '//str(major_radius)//', '//str(minor_radius)// &
                   ' m or segments '//str(n_major)//', '//str(n_minor)// &
                   ': need 0 < minor_radius < major_radius and at least 3 segments each way')
      return
    end if
    allocate (nodes(3, n_major*n_minor), faces(3, 2*n_major*n_minor))
    do i = 1, n_major
      phi = two_pi*real(i - 1, dp)/real(n_major, dp)
      do j = 1, n_minor
        theta = two_pi*real(j - 1, dp)/real(n_minor, dp)
        rho = major_radius + minor_radius*cos(theta)
        nodes(:, torus_node(i, j)) = [rho*cos(phi), rho*sin(phi), minor_radius*sin(theta)]
      end do
    end do
    f = 0
    do i = 1, n_major
      inext = mod(i, n_major) + 1
      do j = 1, n_minor
        jnext = mod(j, n_minor) + 1
        p00 = torus_node(i, j)
        p10 = torus_node(inext, j)
        p11 = torus_node(inext, jnext)
        p01 = torus_node(i, jnext)
        ! d/dphi x d/dtheta points away from the tube centre: (phi, theta) order is outward.
        faces(:, f + 1) = [p00, p10, p11]
        faces(:, f + 2) = [p00, p11, p01]
        f = f + 2
      end do
    end do
    call m%init(nodes, faces, 'torus R='//str(major_radius)//' m, r='//str(minor_radius)//' m, '// &
                str(n_major)//' x '//str(n_minor)//' segments')
  contains
    pure integer function torus_node(ii, jj)
      integer, intent(in) :: ii, jj
      torus_node = (ii - 1)*n_minor + jj
    end function torus_node
  end subroutine torus_mesh

  !> Non-convex L prism: the L profile in x-y, outer size(1) x size(2) [m] with arms of
  !> width thickness [m], extruded size(3) [m] along z, centred at its bounding-box centre.
  !> Before centring the profile is [0,size(1)] x [0,thickness] united with
  !> [0,thickness] x [0,size(2)]. 12 nodes, 20 faces.
  subroutine l_shape_mesh(size, thickness, m)
    real(dp), intent(in) :: size(3), thickness
    type(mesh_t), intent(out) :: m
    real(dp) :: profile(2, 6), nodes(3, 12)
    integer :: faces(3, 20), k, knext, f
    ! Fan of the profile hexagon from its corner 1; all four lie inside the L.
    integer, parameter :: cap(3, 4) = reshape([1, 2, 3, 1, 3, 4, 1, 4, 5, 1, 5, 6], [3, 4])

    if (.not. (all(size > 0.0_dp) .and. thickness > 0.0_dp .and. thickness < min(size(1), size(2)))) then
      call invalid(m, 'l_shape_mesh: invalid size '//str(size(1))//' x '//str(size(2))//' x '//str(size(3))// &
                   ' m or thickness '//str(thickness)//' m: need lengths > 0 and thickness < min(size(1), size(2))')
      return
    end if
    ! Counter-clockwise seen from +z.
    profile(:, 1) = [0.0_dp, 0.0_dp]
    profile(:, 2) = [size(1), 0.0_dp]
    profile(:, 3) = [size(1), thickness]
    profile(:, 4) = [thickness, thickness]
    profile(:, 5) = [thickness, size(2)]
    profile(:, 6) = [0.0_dp, size(2)]
    do k = 1, 6
      nodes(:, k) = [profile(1, k) - 0.5_dp*size(1), profile(2, k) - 0.5_dp*size(2), -0.5_dp*size(3)]
      nodes(:, 6 + k) = [profile(1, k) - 0.5_dp*size(1), profile(2, k) - 0.5_dp*size(2), 0.5_dp*size(3)]
    end do
    f = 0
    do k = 1, 4
      faces(:, f + 1) = 6 + cap(:, k)                     ! top, normal +z
      faces(:, f + 2) = [cap(1, k), cap(3, k), cap(2, k)] ! bottom, normal -z
      f = f + 2
    end do
    do k = 1, 6
      knext = mod(k, 6) + 1
      ! Profile counter-clockwise: (edge direction) x (+z) points out.
      faces(:, f + 1) = [k, knext, 6 + knext]
      faces(:, f + 2) = [k, 6 + knext, 6 + k]
      f = f + 2
    end do
    call m%init(nodes, faces, 'L-prism '//str(size(1))//' x '//str(size(2))//' x '//str(size(3))// &
                ' m, thickness '//str(thickness)//' m')
  end subroutine l_shape_mesh

  !> Star-shaped blob: the icosphere of the given level with each node at distance
  !> radius (1 + amplitude f(u)) [m] along its direction u, where f in [-1, 1] is a smooth
  !> pseudo-random function of direction (a sum of plane waves cos(k.u + phase) with
  !> |k| in [2, 5]) fixed by seed. Needs 0 <= amplitude < 1 so every radius is positive;
  !> the mesh stays closed and outward (each face keeps the orientation of its icosphere
  !> face, being a positive radial scaling of it). Amplitude ~0.3 gives a non-convex body.
  subroutine random_blob_mesh(radius, amplitude, level, seed, m)
    real(dp), intent(in) :: radius, amplitude
    integer, intent(in) :: level, seed
    type(mesh_t), intent(out) :: m
    real(dp), allocatable :: nodes(:, :)
    integer, allocatable :: faces(:, :)
    real(dp) :: wave(3, blob_waves), phase(blob_waves), weight(blob_waves), axis(3), magnitude, f
    integer(i8) :: state
    integer :: k, i

    if (.not. (radius > 0.0_dp .and. amplitude >= 0.0_dp .and. amplitude < 1.0_dp) .or. &
        level < 0 .or. level > max_icosphere_level) then
      call invalid(m, 'random_blob_mesh: invalid radius '//str(radius)//' m, amplitude '//str(amplitude)// &
                   ' or level '//str(level)//': need radius > 0, 0 <= amplitude < 1, level in 0..'// &
                   str(max_icosphere_level))
      return
    end if
    ! Park-Miller "minimal standard" generator (multiplier 48271, modulus 2^31 - 1) in
    ! 64-bit integers: no overflow, identical on every compiler and machine.
    state = 1_i8 + modulo(int(seed, i8), 2147483646_i8)
    do k = 1, blob_waves
      ! Direction uniform enough: a normalised vector from a cube, rejecting tiny ones.
      do
        do i = 1, 3
          call next_uniform(state, axis(i))
        end do
        axis = 2.0_dp*axis - 1.0_dp
        if (norm2(axis) > 0.1_dp .and. norm2(axis) <= 1.0_dp) exit
      end do
      call next_uniform(state, magnitude)
      magnitude = 2.0_dp + 3.0_dp*magnitude
      wave(:, k) = magnitude*axis/norm2(axis)
      call next_uniform(state, phase(k))
      phase(k) = two_pi*phase(k)
      call next_uniform(state, weight(k))
      weight(k) = 0.5_dp + weight(k)
    end do
    weight = weight/sum(weight)

    call unit_icosphere(level, nodes, faces)
    do i = 1, size(nodes, 2)
      f = 0.0_dp
      do k = 1, blob_waves
        f = f + weight(k)*cos(dot_product(wave(:, k), nodes(:, i)) + phase(k))
      end do
      nodes(:, i) = radius*(1.0_dp + amplitude*f)*nodes(:, i)
    end do
    call m%init(nodes, faces, 'blob r='//str(radius)//' m, amplitude '//str(amplitude)//', level '// &
                str(level)//', seed '//str(seed))
  end subroutine random_blob_mesh

  !> Next number x in (0, 1) from the Park-Miller generator (state in 1 .. 2^31 - 2).
  pure subroutine next_uniform(state, x)
    integer(i8), intent(inout) :: state
    real(dp), intent(out) :: x
    integer(i8), parameter :: modulus = 2147483647_i8, multiplier = 48271_i8
    state = modulo(multiplier*state, modulus)
    x = real(state, dp)/real(modulus, dp)
  end subroutine next_uniform

  !> Empty mesh whose source says why nothing was built.
  subroutine invalid(m, why)
    type(mesh_t), intent(out) :: m
    character(len=*), intent(in) :: why
    call m%free()
    allocate (m%nodes(3, 0), m%faces(3, 0))
    m%source = why
  end subroutine invalid

  !> Icosahedron with vertices on the unit sphere: nodes (0, +-1, +-golden) and their
  !> cyclic permutations, normalised; faces counter-clockwise seen from outside.
  pure subroutine unit_icosahedron(nodes, faces)
    real(dp), intent(out) :: nodes(3, 12)
    integer, intent(out) :: faces(3, 20)
    real(dp), parameter :: t = golden
    nodes = reshape([-1.0_dp, t, 0.0_dp, 1.0_dp, t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp, -t, 0.0_dp, &
                     0.0_dp, -1.0_dp, t, 0.0_dp, 1.0_dp, t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp, -t, &
                     t, 0.0_dp, -1.0_dp, t, 0.0_dp, 1.0_dp, -t, 0.0_dp, -1.0_dp, -t, 0.0_dp, 1.0_dp], [3, 12])
    nodes = nodes/sqrt(1.0_dp + t*t)
    faces = 1 + reshape([0, 11, 5, 0, 5, 1, 0, 1, 7, 0, 7, 10, 0, 10, 11, &
                         1, 5, 9, 5, 11, 4, 11, 10, 2, 10, 7, 6, 7, 1, 8, &
                         3, 9, 4, 3, 4, 2, 3, 2, 6, 3, 6, 8, 3, 8, 9, &
                         4, 9, 5, 2, 4, 11, 6, 2, 10, 8, 6, 7, 9, 8, 1], [3, 20])
  end subroutine unit_icosahedron

  !> Unit-sphere icosphere of the given level. Midpoints are shared through a table of the
  !> edges leaving each node towards higher-numbered nodes: in a subdivided icosahedron no
  !> node has more than 6 neighbours, so the table is (6, n_nodes) and a lookup scans at
  !> most 6 entries (flat arrays, no hashing).
  subroutine unit_icosphere(level, nodes, faces)
    integer, intent(in) :: level
    real(dp), allocatable, intent(out) :: nodes(:, :)
    integer, allocatable, intent(out) :: faces(:, :)
    integer, parameter :: max_degree = 6
    real(dp), allocatable :: new_nodes(:, :)
    integer, allocatable :: new_faces(:, :), neighbour(:, :), midpoint(:, :), n_neighbours(:)
    integer :: l, n_nodes, n_faces, f, k, mid(3), corner(3)

    allocate (nodes(3, 12), faces(3, 20))
    call unit_icosahedron(nodes, faces)
    n_nodes = 12
    n_faces = 20
    do l = 1, level
      ! Each level: nodes + edges (= 3/2 faces) nodes, 4 x faces.
      allocate (new_nodes(3, n_nodes + 3*n_faces/2), new_faces(3, 4*n_faces))
      allocate (neighbour(max_degree, n_nodes), midpoint(max_degree, n_nodes), n_neighbours(n_nodes))
      new_nodes(:, 1:n_nodes) = nodes(:, 1:n_nodes)
      n_neighbours = 0
      do f = 1, n_faces
        corner = faces(:, f)
        do k = 1, 3
          call midpoint_node(corner(k), corner(mod(k, 3) + 1), mid(k))
        end do
        ! Corner triangles keep the parent's orientation, the middle one too.
        new_faces(:, 4*f - 3) = [corner(1), mid(1), mid(3)]
        new_faces(:, 4*f - 2) = [mid(1), corner(2), mid(2)]
        new_faces(:, 4*f - 1) = [mid(3), mid(2), corner(3)]
        new_faces(:, 4*f) = [mid(1), mid(2), mid(3)]
      end do
      call move_alloc(new_nodes, nodes)
      call move_alloc(new_faces, faces)
      deallocate (neighbour, midpoint, n_neighbours)
      n_faces = 4*n_faces
    end do
  contains
    !> Node at the (projected) midpoint of edge a-b, created on first use.
    subroutine midpoint_node(a, b, id)
      integer, intent(in) :: a, b
      integer, intent(out) :: id
      integer :: low, high, e
      real(dp) :: p(3)
      low = min(a, b)
      high = max(a, b)
      do e = 1, n_neighbours(low)
        if (neighbour(e, low) == high) then
          id = midpoint(e, low)
          return
        end if
      end do
      n_nodes = n_nodes + 1
      id = n_nodes
      p = nodes(:, low) + nodes(:, high)
      new_nodes(:, id) = p/norm2(p)
      ! Cannot exceed max_degree in an icosphere (degrees are 5 and 6); bounds checking
      ! builds would catch a violation here.
      n_neighbours(low) = n_neighbours(low) + 1
      neighbour(n_neighbours(low), low) = high
      midpoint(n_neighbours(low), low) = id
    end subroutine midpoint_node
  end subroutine unit_icosphere

end module shape_builders
