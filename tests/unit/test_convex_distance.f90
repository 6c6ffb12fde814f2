!> GJK's certified lower bound (convex_distance) against the exact closest-point query
!> (mesh_distance through SKD-trees) on convex shapes: boxes, a thin plate, a tetrahedron
!> and an icosphere (42 vertices), at random poses from 1e-7 m to 2 m apart, plus the cases
!> GJK is known to find hard (parallel faces of aligned boxes, edge on edge, vertex on
!> face).
!> - Never above the exact distance: lower <= exact (1 + 1e-13) + 1e-15 m (both computed
!>   from world points rounded once or twice, a few ulps of the 1 m positions apart).
!> - Sharp: lower >= exact (1 - 1e-6) above gaps of 0.1 mm, and within 0.1 um below (GJK
!>   stops where its support points repeat; on parallel faces its last direction can be off
!>   by 1e-10 rad, measured 3.6e-8 of the gap at worst, 2e-8 m below 0.1 mm: conservative
!>   advancement loses that fraction of a step, nothing else, and takes the exact query in
!>   the band). Hulls 1e-9 m apart may come back not certified (the caller then queries).
!> - Consistent: the separation along the returned normal, recomputed over every vertex
!>   pair, is the returned gap to 1e-13 relative (conservative advancement bounds how fast
!>   that separation closes, so it must be the one reported).
!> - Touching or overlapping hulls: not certified.
program test_convex_distance
  use kinds, only: dp
  use mesh, only: mesh_t
  use error_status, only: error_t
  use skd_tree, only: skd_tree_t
  use mesh_distance, only: mesh_mesh_distance, distance_result_t
  use convex_distance, only: convex_bound_t, convex_lower_bound
  use quaternion, only: quat_rotate, quat_normalize, quat_identity, quat_mul
  use shape_builders, only: tetrahedron_mesh
  use mesh_fixtures, only: box_fixture, icosphere_fixture
  use assertions
  implicit none
  integer, parameter :: n_shapes = 4, n_poses = 4000
  type(mesh_t) :: meshes(n_shapes)
  type(skd_tree_t) :: trees(n_shapes)
  type(error_t) :: err
  real(dp) :: radius(n_shapes)
  real(dp) :: worst_over, worst_under, worst_under_near, worst_sep, mean_iterations, t0, t1, t_gjk, t_exact
  integer :: i, k, a, b, seed_size, n_checked, n_uncertified, iterations_total
  integer, allocatable :: seed(:)

  call random_seed(size=seed_size)
  allocate (seed(seed_size))
  seed = 20261205
  call random_seed(put=seed)
  call box_fixture([0.5_dp, 0.3_dp, 0.2_dp], meshes(1))
  call box_fixture([0.8_dp, 0.8_dp, 0.02_dp], meshes(2))
  call tetrahedron_mesh(0.6_dp, meshes(3))
  call icosphere_fixture(0.4_dp, 1, meshes(4))
  do i = 1, n_shapes
    call trees(i)%build(meshes(i), err)
    call check(err%ok(), 'tree builds')
    radius(i) = maxval(norm2(meshes(i)%nodes, dim=1))
  end do

  worst_over = 0.0_dp
  worst_under = 0.0_dp
  worst_under_near = 0.0_dp
  worst_sep = 0.0_dp
  n_checked = 0
  n_uncertified = 0
  iterations_total = 0
  do k = 1, n_poses
    a = 1 + mod(k, n_shapes)
    b = 1 + mod(k/n_shapes, n_shapes)
    call random_pose_pair(a, b, k)
  end do
  mean_iterations = real(iterations_total, dp)/max(n_checked, 1)
  print '(a, i0, a, i0, a, f6.2)', 'random poses checked: ', n_checked, ', not certified (touching): ', &
    n_uncertified, ', mean support points: ', mean_iterations
  print '(a, es10.2, a, es10.2, a, es10.2, a, es10.2)', 'worst lower above exact (rel): ', worst_over, &
    ', below exact (rel, gaps > 0.1 mm): ', worst_under, ', below exact (gaps <= 0.1 mm) [m]: ', worst_under_near, &
    ', separation mismatch (rel): ', worst_sep
  call check(n_checked > n_poses/2, 'most random poses are apart and checked')
  call check(worst_over <= 1.0e-13_dp, 'the lower bound never exceeds the exact distance')
  call check(worst_under <= 1.0e-6_dp, 'the lower bound is the distance to 1e-6 above 0.1 mm')
  call check(worst_under_near <= 1.0e-7_dp, 'and within 0.1 um below 0.1 mm')
  call check(worst_sep <= 1.0e-13_dp, 'the gap is the separation along the returned normal')

  call hard_cases()
  call touching_cases()
  call timing()
  call test_finish()

contains

  subroutine random_pose_pair(a, b, k)
    integer, intent(in) :: a, b, k
    real(dp) :: qa(4), qb(4), xa(3), xb(3), dir(3), u(4), gap, target_gap
    type(distance_result_t) :: exact
    type(convex_bound_t) :: bound
    call random_number(u)
    qa = quat_normalize(u - 0.5_dp)
    call random_number(u)
    qb = quat_normalize(u - 0.5_dp)
    ! every tenth pose with both aligned: parallel faces and edges
    if (mod(k, 10) == 0) then
      qa = quat_identity
      qb = quat_identity
    end if
    call random_number(xa)
    xa = xa - 0.5_dp
    call random_number(dir)
    dir = dir - 0.5_dp
    dir = dir/norm2(dir)
    ! place B along dir, then slide it to a chosen gap (1e-7 m to 2 m, log-uniform)
    xb = xa + (radius(a) + radius(b) + 0.1_dp)*dir
    call mesh_mesh_distance(trees(a), xa, qa, trees(b), xb, qb, exact)
    call random_number(gap)
    target_gap = 10.0_dp**(-7.0_dp + 7.3_dp*gap)
    xb = xb - (exact%distance - target_gap)*exact%normal
    call mesh_mesh_distance(trees(a), xa, qa, trees(b), xb, qb, exact)
    call convex_lower_bound(meshes(a)%nodes, xa, qa, meshes(b)%nodes, xb, qb, 1.0e-12_dp, 64, bound)
    if (.not. bound%certified) then
      n_uncertified = n_uncertified + 1
      return
    end if
    call compare(a, b, xa, qa, xb, qb, exact%distance, bound)
  end subroutine random_pose_pair

  subroutine compare(a, b, xa, qa, xb, qb, exact, bound)
    integer, intent(in) :: a, b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4), exact
    type(convex_bound_t), intent(in) :: bound
    real(dp) :: sep, scale
    n_checked = n_checked + 1
    iterations_total = iterations_total + bound%iterations
    scale = max(exact, 1.0e-2_dp)         ! (round-off is relative to the 1 m positions)
    worst_over = max(worst_over, (bound%lower - exact)/scale)
    if (exact > 1.0e-4_dp) then
      worst_under = max(worst_under, (exact - bound%lower)/exact)
    else
      worst_under_near = max(worst_under_near, exact - bound%lower)
    end if
    sep = separation_along(a, b, xa, qa, xb, qb, bound%normal)
    worst_sep = max(worst_sep, abs(sep - bound%lower)/scale)
    call check(abs(norm2(bound%normal) - 1.0_dp) < 1.0e-14_dp, 'the normal is a unit vector')
  end subroutine compare

  !> min over B's vertices of n.b minus max over A's of n.a, in world coordinates.
  real(dp) function separation_along(a, b, xa, qa, xb, qb, n) result(sep)
    integer, intent(in) :: a, b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4), n(3)
    real(dp) :: top_a, low_b
    integer :: m
    top_a = -huge(1.0_dp)
    low_b = huge(1.0_dp)
    do m = 1, meshes(a)%n_nodes
      top_a = max(top_a, dot_product(n, xa + quat_rotate(qa, meshes(a)%nodes(:, m))))
    end do
    do m = 1, meshes(b)%n_nodes
      low_b = min(low_b, dot_product(n, xb + quat_rotate(qb, meshes(b)%nodes(:, m))))
    end do
    sep = low_b - top_a
  end function separation_along

  !> Aligned boxes face on face (the whole face pair is closest: GJK's simplex may cycle
  !> over it), edge on edge crossed at 90 degrees, a vertex over a face centre; each at gaps
  !> from 1e-9 m to 0.5 m: the bound is the known gap to 1e-12.
  subroutine hard_cases()
    real(dp), parameter :: gaps(5) = [1.0e-9_dp, 1.0e-6_dp, 1.0e-3_dp, 0.1_dp, 0.5_dp]
    real(dp) :: q45(4), qv(4), xb(3), h
    type(convex_bound_t) :: bound
    integer :: g
    do g = 1, size(gaps)
      ! face on face: box 1 (half sizes 0.5 x 0.3 x 0.2) on itself along z
      xb = [0.05_dp, -0.03_dp, 0.4_dp + gaps(g)]
      call convex_lower_bound(meshes(1)%nodes, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, meshes(1)%nodes, xb, &
                              quat_identity, 1.0e-12_dp, 64, bound)
      call check(bound%certified .or. gaps(g) < 1.0e-7_dp, 'face on face is certified')
      if (bound%certified) then
        call check_close(bound%lower, gaps(g), 1.0e-6_dp, 'face on face: the gap', atol=1.0e-9_dp)
        call check(bound%lower <= gaps(g)*(1.0_dp + 1.0e-13_dp) + 1.0e-15_dp, 'face on face: never above')
        call check_close_array(bound%normal, [0.0_dp, 0.0_dp, 1.0_dp], 1.0e-9_dp, 'face on face: the normal', &
                               atol=1.0e-9_dp)
      end if
      ! edge on edge: box 1 turned 90 degrees about z on top of itself, both turned 45
      ! degrees about their long axis so that edges face each other
      q45 = quat_normalize([cos(acos(-1.0_dp)/8.0_dp), sin(acos(-1.0_dp)/8.0_dp), 0.0_dp, 0.0_dp])
      qv = quat_normalize([cos(acos(-1.0_dp)/4.0_dp), 0.0_dp, 0.0_dp, sin(acos(-1.0_dp)/4.0_dp)])
      h = (0.3_dp + 0.2_dp)*sqrt(0.5_dp)      ! the reach along z of the cross-section turned 45 degrees
      call edge_case(q45, qv, h, gaps(g))
      ! vertex on face: the tetrahedron (a vertex pointing down along -z after the turn) over
      ! the thin plate's top face
      call vertex_case(gaps(g))
    end do
  end subroutine hard_cases

  subroutine edge_case(q45, qv, h, gap)
    real(dp), intent(in) :: q45(4), qv(4), h, gap
    real(dp) :: qb(4), xb(3)
    type(distance_result_t) :: exact
    type(convex_bound_t) :: bound
    qb = quat_normalize(quat_mul(qv, q45))
    xb = [0.0_dp, 0.0_dp, 2.0_dp*h + gap]
    call mesh_mesh_distance(trees(1), [0.0_dp, 0.0_dp, 0.0_dp], q45, trees(1), xb, qb, exact)
    call convex_lower_bound(meshes(1)%nodes, [0.0_dp, 0.0_dp, 0.0_dp], q45, meshes(1)%nodes, xb, qb, 1.0e-12_dp, &
                            64, bound)
    call check(bound%certified .or. gap < 1.0e-7_dp, 'edge on edge is certified')
    call check_close(bound%lower, exact%distance, 1.0e-6_dp, 'edge on edge: the exact gap', atol=1.0e-9_dp)
    call check(bound%lower <= exact%distance*(1.0_dp + 1.0e-13_dp) + 1.0e-15_dp, 'edge on edge: never above')
  end subroutine edge_case

  subroutine vertex_case(gap)
    real(dp), intent(in) :: gap
    real(dp) :: lowest, xa(3)
    type(convex_bound_t) :: bound
    type(distance_result_t) :: exact
    ! the tetrahedron as built has a vertex at (1,1,1) s and one at (1,-1,-1) s ... take B =
    ! the tetrahedron, A = the plate below it: its lowest vertex lies gap above the plate
    lowest = minval(meshes(3)%nodes(3, :))
    xa = [0.0_dp, 0.0_dp, -0.02_dp]             ! plate top face at z = 0
    call convex_lower_bound(meshes(2)%nodes, xa, quat_identity, meshes(3)%nodes, [0.0_dp, 0.0_dp, gap - lowest], &
                            quat_identity, 1.0e-12_dp, 64, bound)
    call mesh_mesh_distance(trees(2), xa, quat_identity, trees(3), [0.0_dp, 0.0_dp, gap - lowest], quat_identity, &
                            exact)
    call check(bound%certified .or. gap < 1.0e-7_dp, 'vertex (edge) on face is certified')
    call check_close(bound%lower, exact%distance, 1.0e-6_dp, 'vertex on face: the exact gap', atol=1.0e-9_dp)
    call check(bound%lower <= exact%distance*(1.0_dp + 1.0e-13_dp) + 1.0e-15_dp, 'vertex on face: never above')
  end subroutine vertex_case

  !> Hulls that touch or overlap are never certified.
  subroutine touching_cases()
    type(convex_bound_t) :: bound
    call convex_lower_bound(meshes(1)%nodes, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, meshes(1)%nodes, &
                            [0.1_dp, 0.0_dp, 0.1_dp], quat_identity, 1.0e-12_dp, 64, bound)
    call check(.not. bound%certified, 'overlapping boxes are not certified')
    call check(bound%lower == 0.0_dp, 'and report no separation')
    call convex_lower_bound(meshes(1)%nodes, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, meshes(1)%nodes, &
                            [0.0_dp, 0.0_dp, 0.2_dp], quat_identity, 1.0e-12_dp, 64, bound)
    call check(.not. bound%certified .or. bound%lower <= 1.0e-15_dp, 'boxes face to face at zero gap: no separation')
  end subroutine touching_cases

  !> Cost per query of each, two cubes' worth of boxes near contact (printed, not checked:
  !> speed lives in the benchmarks).
  subroutine timing()
    integer, parameter :: repeats = 20000
    real(dp) :: qa(4), qb(4), xb(3), u(4), sink
    type(distance_result_t) :: exact
    type(convex_bound_t) :: bound
    integer :: r
    call random_number(u)
    qa = quat_normalize(u - 0.5_dp)
    call random_number(u)
    qb = quat_normalize(u - 0.5_dp)
    xb = [0.0_dp, 0.0_dp, 0.62_dp]
    sink = 0.0_dp
    call cpu_time(t0)
    do r = 1, repeats
      call convex_lower_bound(meshes(1)%nodes, [0.0_dp, 0.0_dp, 0.0_dp], qa, meshes(1)%nodes, &
                              xb + 1.0e-9_dp*r, qb, 1.0e-12_dp, 64, bound)
      sink = sink + bound%lower
    end do
    call cpu_time(t1)
    t_gjk = (t1 - t0)/repeats
    call cpu_time(t0)
    do r = 1, repeats
      call mesh_mesh_distance(trees(1), [0.0_dp, 0.0_dp, 0.0_dp], qa, trees(1), xb + 1.0e-9_dp*r, qb, exact)
      sink = sink + exact%distance
    end do
    call cpu_time(t1)
    t_exact = (t1 - t0)/repeats
    print '(a, f8.3, a, f8.3, a, es10.2, a)', 'box-box near contact: GJK bound ', 1.0e6_dp*t_gjk, &
      ' us, exact query ', 1.0e6_dp*t_exact, ' us per query (', sink, ')'
  end subroutine timing

end program test_convex_distance
