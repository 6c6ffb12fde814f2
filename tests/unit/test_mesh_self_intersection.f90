!> mesh_self_intersection: the triangle pair test on each kind of contact (disjoint,
!> touching at a vertex or along an edge, crossing, coplanar overlapping or only adjacent,
!> sharing an edge flat, bent or folded, sharing a vertex crossing or not), the tolerance
!> on both sides, and the search over whole meshes: built-in closed shapes have no crossing
!> pair, two overlapping boxes do, and the number of pairs tested grows like the face count.
program test_mesh_self_intersection
  use kinds, only: dp, i8
  use mesh, only: mesh_t
  use mesh_self_intersection, only: triangles_cross, find_self_intersections, self_intersection_stats_t
  use shape_builders, only: box_mesh, torus_mesh, icosphere_mesh, l_shape_mesh, random_blob_mesh
  use assertions
  implicit none
  ! Unit-sized triangles: 1e-9 is far above the round-off of their distances (1e-16) and
  ! far below the depths of the deliberate crossings (>= 1e-3).
  real(dp), parameter :: tol = 1.0e-9_dp
  real(dp) :: base(3, 3), t(3, 3), p(3)
  logical :: crossing
  type(mesh_t) :: m, a, b
  integer(i8) :: n_pairs
  integer :: pair(2)
  type(self_intersection_stats_t) :: stats
  real(dp) :: per_face(2)
  integer :: level

  ! base: right triangle in the plane z = 0.
  base = reshape([0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp], [3, 3])

  ! Disjoint: the same triangle lifted by 1.
  t = base
  t(3, :) = 1.0_dp
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'disjoint parallel triangles do not cross')

  ! Crossing: a vertical triangle through the interior of base, from z = -0.5 to z = 0.5.
  t = reshape([0.2_dp, 0.2_dp, -0.5_dp, 0.2_dp, 0.2_dp, 0.5_dp, 0.6_dp, 0.2_dp, 0.5_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(crossing, 'a triangle through the interior crosses')
  call check(abs(p(3)) < 1.0e-12_dp .and. abs(p(2) - 0.2_dp) < 1.0e-12_dp, 'crossing point on both planes')
  call triangles_cross(t, base, tol, crossing, p)
  call check(crossing, 'crossing is symmetric')

  ! Touching: the vertical triangle lifted so that one vertex rests on base's interior.
  t = reshape([0.2_dp, 0.2_dp, 0.0_dp, 0.2_dp, 0.2_dp, 1.0_dp, 0.6_dp, 0.2_dp, 1.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'a vertex resting on the interior touches, does not cross')
  ! ... and an edge lying in base's plane, the rest above: touching along a segment.
  t = reshape([0.1_dp, 0.1_dp, 0.0_dp, 0.5_dp, 0.1_dp, 0.0_dp, 0.3_dp, 0.1_dp, 1.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'an edge lying on the interior touches, does not cross')

  ! Tolerance: the vertex pushed 1e-10 (< tol) through touches; 1e-3 through crosses.
  t = reshape([0.2_dp, 0.2_dp, -1.0e-10_dp, 0.2_dp, 0.2_dp, 1.0_dp, 0.6_dp, 0.2_dp, 1.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'a vertex 1e-10 below the plane (tolerance 1e-9) touches')
  t(3, 1) = -1.0e-3_dp
  call triangles_cross(base, t, tol, crossing, p)
  call check(crossing, 'a vertex 1e-3 below the plane crosses')

  ! Coplanar overlapping: base shifted by (0.2, 0.2) in its plane.
  t = base
  t(1:2, :) = t(1:2, :) + 0.2_dp
  call triangles_cross(base, t, tol, crossing, p)
  call check(crossing, 'coplanar overlapping triangles cross')
  call check(p(1) + p(2) < 1.0_dp .and. p(1) > 0.2_dp .and. p(2) > 0.2_dp .and. p(3) == 0.0_dp, &
             'coplanar overlap point inside both')
  ! Coplanar, apart.
  t = base
  t(1, :) = t(1, :) + 2.0_dp
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'coplanar triangles apart do not cross')

  ! Sharing an edge (1,0,0)-(0,1,0): flat (the other triangle of a unit square), bent, folded.
  t = reshape([1.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'flat neighbours sharing an edge do not cross')
  t(3, 2) = 0.5_dp
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'bent neighbours sharing an edge do not cross')
  t = reshape([1.0_dp, 0.0_dp, 0.0_dp, 0.2_dp, 0.2_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(crossing, 'neighbours folded onto each other (coplanar, same side of the edge) cross')
  ! Folded almost flat onto base, but 1e-3 above it: they meet only along the edge.
  t(3, 2) = 1.0e-3_dp
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'neighbours folded to a thin wedge do not cross')

  ! Sharing the vertex (0,0,0): a triangle going down through base's interior crosses it
  ! away from the vertex; one going down outside base meets it at the vertex only.
  t = reshape([0.0_dp, 0.0_dp, 0.0_dp, 0.5_dp, 0.1_dp, -0.5_dp, 0.1_dp, 0.5_dp, 0.5_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(crossing, 'sharing a vertex, crossing away from it')
  call check(norm2(p) > 1.0e-3_dp, 'the crossing point is away from the shared vertex')
  t = reshape([0.0_dp, 0.0_dp, 0.0_dp, -0.5_dp, -0.1_dp, -0.5_dp, -0.1_dp, -0.5_dp, 0.5_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'sharing a vertex, the planes'' common line leaves it on opposite sides')
  t = reshape([0.0_dp, 0.0_dp, 0.0_dp, -0.5_dp, 0.0_dp, 0.5_dp, 0.0_dp, -0.5_dp, 0.5_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'sharing a vertex, one side of each other''s plane')
  ! Coplanar, sharing the vertex: angular sectors apart, then overlapping.
  t = reshape([0.0_dp, 0.0_dp, 0.0_dp, -1.0_dp, 0.0_dp, 0.0_dp, -1.0_dp, -1.0_dp, 0.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(.not. crossing, 'coplanar, sharing a vertex, sectors apart')
  t = reshape([0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 1.0_dp, 0.0_dp, -1.0_dp, 1.0_dp, 0.0_dp], [3, 3])
  call triangles_cross(base, t, tol, crossing, p)
  call check(crossing, 'coplanar, sharing a vertex, sectors overlapping')

  ! Whole meshes. Built-in closed shapes: no pair crosses (their box faces are split along
  ! diagonals into coplanar neighbours, their tori and spheres have vertices shared by six).
  call box_mesh([1.0_dp, 2.0_dp, 3.0_dp], m)
  call expect_clean(m, 'box')
  call torus_mesh(1.0_dp, 0.25_dp, 48, 24, m)
  call expect_clean(m, 'torus')
  call l_shape_mesh([1.0_dp, 1.0_dp, 0.3_dp], 0.2_dp, m)
  call expect_clean(m, 'L prism')
  call random_blob_mesh(1.0_dp, 0.2_dp, 3, 7, m)
  call expect_clean(m, 'random blob')

  ! Two boxes in one mesh, the second shifted by half a side: their surfaces cross.
  call box_mesh([1.0_dp, 1.0_dp, 1.0_dp], a)
  call box_mesh([1.0_dp, 1.0_dp, 1.0_dp], b)
  b%nodes = b%nodes + 0.5_dp
  call m%init(reshape([a%nodes, b%nodes], [3, a%n_nodes + b%n_nodes]), &
              reshape([a%faces, b%faces + a%n_nodes], [3, a%n_faces + b%n_faces]), 'two boxes')
  call find_self_intersections(m, 1.0e-9_dp, n_pairs, pair, p)
  call check(n_pairs > 0, 'two overlapping boxes: crossing pairs found')
  call check(pair(1) <= a%n_faces .and. pair(2) > a%n_faces, 'the first pair joins a face of each box')
  ! (a is [-0.5, 0.5]^3, b is [0, 1]^3: their surfaces cross on the boundary of [0, 0.5]^3)
  call check(all(p >= -1.0e-12_dp .and. p <= 0.5_dp + 1.0e-12_dp), 'the crossing point lies in both boxes')
  ! Shifted apart (touching face to face at x = 1 is not crossing, the faces only touch).
  b%nodes = b%nodes - 0.5_dp
  b%nodes(1, :) = b%nodes(1, :) + 1.0_dp
  call m%init(reshape([a%nodes, b%nodes], [3, a%n_nodes + b%n_nodes]), &
              reshape([a%faces, b%faces + a%n_nodes], [3, a%n_faces + b%n_faces]), 'two boxes side by side')
  call find_self_intersections(m, 1.0e-9_dp, n_pairs, pair, p)
  call check(n_pairs > 0, 'two boxes sharing a face area (coincident sheets, opposite normals) overlap')

  ! Cost: pair tests per face stay bounded as the icosphere is refined 16-fold (O(n log n)
  ! search, the pairs near each face being a fixed number); an all-pairs search would
  ! grow 16-fold per face. A factor 2 allows for the hierarchy's uneven leaves.
  do level = 3, 5, 2
    call icosphere_mesh(1.0_dp, level, m)
    call find_self_intersections(m, 1.0e-9_dp, n_pairs, pair, p, stats)
    call check(n_pairs == 0, 'icosphere level '//char(iachar('0') + level)//': no crossing')
    per_face((level - 1)/2) = real(stats%n_pair_tests, dp)/m%n_faces
  end do
  call check(per_face(2) < 2.0_dp*per_face(1), 'pair tests per face bounded under refinement')
  call test_finish()

contains

  subroutine expect_clean(mm, what)
    type(mesh_t), intent(in) :: mm
    character(len=*), intent(in) :: what
    real(dp) :: lower(3), upper(3)
    call mm%bounds(lower, upper)
    call find_self_intersections(mm, 1.0e-8_dp*norm2(upper - lower), n_pairs, pair, p)
    call check(n_pairs == 0 .and. all(pair == 0), what//': no crossing pair')
  end subroutine expect_clean

end program test_mesh_self_intersection
