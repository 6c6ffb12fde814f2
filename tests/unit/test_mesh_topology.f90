!> mesh_topology on meshes built by hand: edge counts, Euler characteristic, adjacency
!> consistency, outward flip, unused-node removal, and each refusal (open, non-manifold,
!> inconsistent orientation, missing node, repeated node, zero volume).
program test_mesh_topology
  use kinds, only: dp
  use mesh, only: mesh_t
  use mesh_topology, only: build_mesh_topology, signed_volume, vertex_fan_count, component_count
  use error_status, only: error_t, ERR_MESH
  use assertions
  implicit none
  real(dp) :: cube_nodes(3, 8), tet_nodes(3, 4)
  integer :: cube_faces(3, 12), tet_faces(3, 4), i
  type(mesh_t) :: m
  type(error_t) :: err

  ! Unit cube: node 1 + x + 2y + 4z at (x, y, z); two outward CCW triangles per side.
  do i = 1, 8
    cube_nodes(:, i) = real([mod(i - 1, 2), mod((i - 1)/2, 2), (i - 1)/4], dp)
  end do
  cube_faces = reshape([1, 3, 4, 1, 4, 2, &   ! z = 0
                        5, 6, 8, 5, 8, 7, &   ! z = 1
                        1, 2, 6, 1, 6, 5, &   ! y = 0
                        3, 7, 8, 3, 8, 4, &   ! y = 1
                        1, 5, 7, 1, 7, 3, &   ! x = 0
                        2, 4, 8, 2, 8, 6], [3, 12])   ! x = 1
  tet_nodes = reshape([0, 0, 0, 1, 0, 0, 0, 1, 0, 0, 0, 1]*1.0_dp, [3, 4])
  tet_faces = reshape([1, 3, 2, 1, 2, 4, 1, 4, 3, 2, 3, 4], [3, 4])

  ! Tetrahedron: 6 edges, V - E + F = 2, volume 1/6 (exact inputs; the sum of four small
  ! determinants about the box centre rounds at the 1e-16 level, 1e-14 is ample).
  call m%init(tet_nodes, tet_faces, 'tetrahedron')
  call build_mesh_topology(m, err)
  call check(err%ok(), 'tetrahedron accepted')
  call check(m%n_edges == 6, 'tetrahedron has 6 edges')
  call check(m%n_nodes - m%n_edges + m%n_faces == 2, 'tetrahedron: V - E + F = 2')
  call check_close(signed_volume(m), 1.0_dp/6.0_dp, 1.0e-14_dp, 'tetrahedron volume 1/6')
  call check_adjacency(m, 'tetrahedron')

  ! Cube: 18 edges (12 sides + 6 diagonals), V - E + F = 2, volume exactly 1 (all
  ! coordinates are 0 or 1 and the centre is 0.5: every product is exact).
  call m%init(cube_nodes, cube_faces, 'cube')
  call build_mesh_topology(m, err)
  call check(err%ok(), 'cube accepted')
  call check(m%n_edges == 18, 'cube has 18 edges')
  call check(m%n_nodes - m%n_edges + m%n_faces == 2, 'cube: V - E + F = 2')
  call check(signed_volume(m) == 1.0_dp, 'cube volume exactly 1')
  call check(all(m%faces == cube_faces), 'outward cube is not flipped')
  call check(vertex_fan_count(m) == 8 .and. component_count(m) == 1, 'cube: 8 fans, one component')
  call check_adjacency(m, 'cube')

  ! Inward cube (every face reversed): flipped, volume becomes +1, adjacency still right.
  call m%init(cube_nodes, cube_faces([1, 3, 2], :), 'inward cube')
  call check(signed_volume(m) == -1.0_dp, 'inward cube starts with volume -1')
  call build_mesh_topology(m, err)
  call check(err%ok(), 'inward cube accepted')
  call check(signed_volume(m) == 1.0_dp, 'inward cube flipped to volume +1')
  call check(all(m%face_normal(1) == [0.0_dp, 0.0_dp, -1.0_dp]), 'flipped bottom face points down (outward)')
  call check_adjacency(m, 'flipped cube')

  ! Unused node in front (index 1) and at the end: dropped and the faces renumbered.
  call m%init(reshape([[5.0_dp, 5.0_dp, 5.0_dp], reshape(cube_nodes, [24]), [-7.0_dp, 0.0_dp, 0.0_dp]], [3, 10]), &
              cube_faces + 1, 'cube with unused nodes')
  call build_mesh_topology(m, err)
  call check(err%ok(), 'unused nodes are not an error')
  call check(m%n_nodes == 8, 'unused nodes dropped')
  call check(all(m%nodes == cube_nodes) .and. all(m%faces == cube_faces), 'renumbering keeps the node order')
  call check(signed_volume(m) == 1.0_dp, 'cube with unused nodes: volume 1')
  call check_adjacency(m, 'cube with unused nodes')

  ! Two disjoint cubes: allowed; 36 edges, two components, volume 2.
  call m%init(reshape([reshape(cube_nodes, [24]), reshape(cube_nodes + 3.0_dp, [24])], [3, 16]), &
              reshape([reshape(cube_faces, [36]), reshape(cube_faces + 8, [36])], [3, 24]), 'two cubes')
  call build_mesh_topology(m, err)
  call check(err%ok(), 'two disjoint cubes accepted')
  call check(m%n_edges == 36 .and. component_count(m) == 2, 'two cubes: 36 edges, 2 components')
  call check(m%n_nodes - m%n_edges + m%n_faces == 4, 'two spheres: V - E + F = 4')
  call check(signed_volume(m) == 2.0_dp, 'two cubes: volume 2')

  ! Two tetrahedra touching at one vertex (a pinched vertex, every edge still shared by
  ! two faces): accepted, and the pinch shows as one fan more than there are nodes.
  call m%init(reshape([reshape(tet_nodes, [12]), reshape(-tet_nodes(:, 2:4), [9])], [3, 7]), &
              reshape([reshape(tet_faces, [12]), 1, 5, 6, 1, 7, 5, 1, 6, 7, 5, 7, 6], [3, 8]), 'pinched tetrahedra')
  call build_mesh_topology(m, err)
  call check(err%ok(), 'pinched pair of tetrahedra accepted')
  call check(vertex_fan_count(m) == m%n_nodes + 1, 'pinched vertex: one extra fan')
  call check(vertex_fan_count(m) - m%n_edges + m%n_faces == 4, 'pinched: fans - E + F = 2 per genus-0 piece')
  call check_close(signed_volume(m), 2.0_dp/6.0_dp, 1.0e-14_dp, 'pinched tetrahedra volume 2/6')
  call check_adjacency(m, 'pinched tetrahedra')

  ! Open: cube without its top (faces 3 and 4): the 4 edges of the top square are
  ! boundary edges; the first in (smaller node, larger node) order is 5-6.
  call err%clear()
  call m%init(cube_nodes, cube_faces(:, [1, 2, 5, 6, 7, 8, 9, 10, 11, 12]), 'open box')
  call build_mesh_topology(m, err)
  call check(err%code == ERR_MESH, 'open box: ERR_MESH')
  call check_error(err%code, err%message, [character(len=70) :: "mesh 'open box'", 'open surface', &
                   '4 boundary edge(s)', 'nodes 5 (0.00000000, 0.00000000, 1.00000000) and 6 (1.00000000, 0.0'], &
                   'open box refused naming the count and the first boundary edge')
  call check(.not. m%has_topology(), 'refused mesh gets no topology')
  call check(index(err%message, 'non-manifold') == 0 .and. index(err%message, 'orientation') == 0, &
             'open box: no other defect reported')

  ! Non-manifold: a third face on tetrahedron edge 1-2 (new node 5), which also leaves
  ! its two other edges open.
  call err%clear()
  call m%init(reshape([reshape(tet_nodes, [12]), 0.5_dp, -1.0_dp, -1.0_dp], [3, 5]), &
              reshape([reshape(tet_faces, [12]), 1, 2, 5], [3, 5]), 'fin')
  call build_mesh_topology(m, err)
  call check_error(err%code, err%message, [character(len=50) :: "mesh 'fin'", 'non-manifold', &
                   '1 edge(s) used by more than two faces', 'nodes 1 (', 'used by 3 faces', &
                   '2 boundary edge(s)'], 'three faces on one edge refused')

  ! Non-manifold and closed: two tetrahedra sharing one edge (1-2), four faces on it.
  call err%clear()
  call m%init(reshape([reshape(tet_nodes, [12]), 0.0_dp, -1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, -1.0_dp], [3, 6]), &
              reshape([reshape(tet_faces, [12]), 1, 5, 2, 1, 6, 5, 1, 2, 6, 2, 5, 6], [3, 8]), 'bowtie')
  call build_mesh_topology(m, err)
  call check_error(err%code, err%message, [character(len=50) :: 'non-manifold', 'used by 4 faces', &
                   'edge between nodes 1 (', ' and 2 ('], 'two tetrahedra on one edge refused')
  call check(index(err%message, 'open') == 0, 'bowtie is closed: no boundary edges reported')

  ! Inconsistent orientation: one triangle of the cube (7: nodes 3, 7, 8) reversed; its 3
  ! edges are each traversed twice in the same direction, the first (3-7) also by face 10.
  call err%clear()
  call m%init(cube_nodes, cube_faces, 'cube with a flipped face')
  m%faces(:, 7) = cube_faces([1, 3, 2], 7)
  call build_mesh_topology(m, err)
  call check_error(err%code, err%message, [character(len=70) :: "mesh 'cube with a flipped face'", &
                   'inconsistent orientation', '3 edge(s)', 'edge between nodes 3 (0.00000000, 1.00000000, 0.00000000) and 7 (', &
                   'in faces 7 and 10'], &
                   'one flipped face refused, naming an edge')
  call check(index(err%message, 'open') == 0, 'flipped face: closed, so no boundary edges reported')

  ! Face referring to a missing node.
  call err%clear()
  call m%init(tet_nodes, tet_faces, 'bad index')
  m%faces(2, 3) = 9
  call build_mesh_topology(m, err)
  call check_error(err%code, err%message, [character(len=40) :: 'missing nodes', 'face 3 refers to node 9', &
                   '4 nodes'], 'missing node refused')

  ! Face using one node twice.
  call err%clear()
  call m%init(tet_nodes, tet_faces, 'repeated node')
  m%faces(3, 4) = 2
  call build_mesh_topology(m, err)
  call check_error(err%code, err%message, [character(len=40) :: 'degenerate', 'face 4'], 'repeated node refused')

  ! Zero volume: a triangle glued to its reverse is closed, manifold and consistently
  ! oriented but encloses nothing.
  call err%clear()
  call m%init(tet_nodes(:, 1:3), reshape([1, 2, 3, 1, 3, 2], [3, 2]), 'pillow')
  call build_mesh_topology(m, err)
  call check_error(err%code, err%message, [character(len=40) :: "mesh 'pillow'", 'encloses no volume'], &
                   'zero-volume surface refused')

  call test_finish()

contains

  !> Every edge sorted and listed once per face use, face_edges(k,f) joining face nodes k
  !> and k+1, edge_faces(1,e) running from the smaller node to the larger and
  !> edge_faces(2,e) back: the invariants collision code will rely on.
  subroutine check_adjacency(m, name)
    type(mesh_t), intent(in) :: m
    character(len=*), intent(in) :: name
    integer :: f, k, e, a, b, uses(m%n_edges)
    logical :: ok
    ok = size(m%edges, 2) == m%n_edges .and. size(m%edge_faces, 2) == m%n_edges &
         .and. size(m%face_edges, 2) == m%n_faces
    ok = ok .and. all(m%edges(1, :) < m%edges(2, :))
    uses = 0
    do f = 1, m%n_faces
      do k = 1, 3
        a = m%faces(k, f)
        b = m%faces(mod(k, 3) + 1, f)
        e = m%face_edges(k, f)
        uses(e) = uses(e) + 1
        ok = ok .and. m%edges(1, e) == min(a, b) .and. m%edges(2, e) == max(a, b)
        if (a < b) then
          ok = ok .and. m%edge_faces(1, e) == f
        else
          ok = ok .and. m%edge_faces(2, e) == f
        end if
      end do
    end do
    ok = ok .and. all(uses == 2)
    call check(ok, name//': edges, face_edges and edge_faces consistent')
  end subroutine check_adjacency

end program test_mesh_topology
