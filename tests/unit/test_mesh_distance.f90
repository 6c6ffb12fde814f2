!> Mesh-mesh distance through SKD-trees against the brute-force reference on 10,000+ random
!> pose pairs over convex and non-convex shapes, contrived cases with hand-worked answers,
!> spheres, the upper bound, and the pruning itself (far bodies test few primitives).
program test_mesh_distance
  use kinds, only: dp, i8
  use mesh, only: mesh_t
  use error_status, only: error_t
  use skd_tree, only: skd_tree_t, LEAF_SIZE
  use mesh_distance
  use quaternion, only: quat_identity
  use mesh_fixtures
  use assertions
  implicit none
  integer, parameter :: n_shapes = 7
  type(mesh_t) :: meshes(n_shapes)
  type(skd_tree_t) :: trees(n_shapes)
  type(error_t) :: err
  real(dp) :: radius(n_shapes)
  integer :: i, j, seed_size
  integer, allocatable :: seed(:)
  integer :: n_poses_total

  call random_seed(size=seed_size)
  allocate (seed(seed_size))
  seed = 20261122
  call random_seed(put=seed)

  call box_fixture([0.5_dp, 0.3_dp, 0.2_dp], meshes(1))
  call box_fixture([0.8_dp, 0.8_dp, 0.02_dp], meshes(2))                ! thin plate
  call icosphere_fixture(0.5_dp, 1, meshes(3))
  call torus_fixture(0.6_dp, 0.2_dp, 8, 6, meshes(4))
  call l_prism_fixture(0.4_dp, 0.3_dp, meshes(5))
  call blob_fixture(0.5_dp, 1, 0.3_dp, [0.3_dp, 1.1_dp, 2.0_dp], meshes(6))
  call blob_fixture(0.5_dp, 2, 0.35_dp, [1.3_dp, 0.1_dp, 0.7_dp], meshes(7))   ! 320 faces
  do i = 1, n_shapes
    call trees(i)%build(meshes(i), err)
    call check(err%ok(), 'tree builds for shape '//char(48 + i))
    radius(i) = maxval(norm2(meshes(i)%nodes, dim=1))
    call check_tree(trees(i), meshes(i))
  end do

  ! Random poses against brute force: every pair of the six small shapes 300 times (36 x 300
  ! = 10,800), the 320-face blob against each 40 times.
  n_poses_total = 0
  do i = 1, 6
    do j = 1, 6
      call random_pairs(i, j, 300)
    end do
  end do
  do j = 1, 6
    call random_pairs(7, j, 40)
  end do
  call check(n_poses_total >= 10000, 'at least 10,000 random pose pairs compared')

  call bad_mesh()
  call contrived_cases()
  call sphere_cases()
  call bound_and_pruning()
  call test_finish()

contains

  !> Structure: every face in exactly one leaf, leaves within LEAF_SIZE, boxes enclose
  !> their faces and nest, each vertex and edge owned exactly once.
  subroutine check_tree(tree, m)
    type(skd_tree_t), intent(in) :: tree
    type(mesh_t), intent(in) :: m
    integer :: k, s, v, n_leaf_faces, n_owned_v, n_owned_e
    logical :: ok_box, ok_nest
    integer, allocatable :: seen(:)
    allocate (seen(m%n_faces))
    seen = 0
    n_leaf_faces = 0
    ok_box = .true.
    ok_nest = .true.
    do k = 1, tree%n_boxes
      do s = tree%first(k), tree%first(k) + tree%count(k) - 1
        do v = 1, 3
          ! centre +- half extents reproduce the bounds to rounding: 1e-15 of the size
          if (any(abs(matmul(tree%tri(:, v, s) - tree%box(1:3, k), reshape(tree%box(7:15, k), [3, 3]))) > &
                  tree%box(4:6, k) + 1.0e-15_dp*tree%radius)) ok_box = .false.
        end do
      end do
      if (tree%right(k) == 0) then
        n_leaf_faces = n_leaf_faces + tree%count(k)
        if (tree%count(k) > LEAF_SIZE) ok_box = .false.
        seen(tree%face_id(tree%first(k):tree%first(k) + tree%count(k) - 1)) = &
          seen(tree%face_id(tree%first(k):tree%first(k) + tree%count(k) - 1)) + 1
      else
        if (tree%count(k + 1) + tree%count(tree%right(k)) /= tree%count(k)) ok_nest = .false.
        if (abs(tree%count(k + 1) - tree%count(tree%right(k))) > 1) ok_nest = .false.
      end if
    end do
    call check(ok_box .and. ok_nest, 'tree of '//m%source//': boxes enclose faces, children split evenly')
    call check(all(seen == 1) .and. n_leaf_faces == m%n_faces, 'tree of '//m%source//': every face in one leaf')
    n_owned_v = 0
    n_owned_e = 0
    do s = 1, tree%n_faces
      do v = 1, 3
        if (btest(tree%flags(s), v - 1)) n_owned_v = n_owned_v + 1
        if (btest(tree%flags(s), v + 2)) n_owned_e = n_owned_e + 1
      end do
    end do
    ! closed genus-g surface: E = 3F/2, and V is the node count (all nodes are used)
    call check(n_owned_v == m%n_nodes, 'tree of '//m%source//': every vertex owned once')
    call check(2*n_owned_e == 3*m%n_faces, 'tree of '//m%source//': every edge owned once')
  end subroutine check_tree

  !> B placed at a random direction from A, centre distance from 0.4 to 2 times the sum of
  !> bounding radii: crossing, touching-close, near and far. Tolerance: 1e-12 relative, plus
  !> 1e-14 of the body size absolute, the rounding of the coordinates themselves (the tree
  !> and the reference evaluate the same primitive formulas in the same frame, but edges
  !> may be taken in opposite directions).
  subroutine random_pairs(ia, ib, n)
    integer, intent(in) :: ia, ib, n
    type(distance_result_t) :: fast, ref
    real(dp) :: xa(3), qa(4), xb(3), qb(4), u(1), worst, scale, err_d
    integer :: k, n_bad, n_geom_bad
    n_bad = 0
    n_geom_bad = 0
    worst = 0.0_dp
    scale = radius(ia) + radius(ib)
    do k = 1, n
      call random_number(u)
      qa = random_unit_quaternion()
      qb = random_unit_quaternion()
      call random_number(xa)
      xa = xa - 0.5_dp
      xb = xa + (0.4_dp + 1.6_dp*u(1))*scale*random_unit_vector()
      call mesh_mesh_distance(trees(ia), xa, qa, trees(ib), xb, qb, fast)
      call mesh_mesh_distance_brute(meshes(ia), xa, qa, meshes(ib), xb, qb, ref)
      err_d = abs(fast%distance - ref%distance)
      if (err_d > 1.0e-12_dp*ref%distance + 1.0e-14_dp*scale) n_bad = n_bad + 1
      if (ref%distance > 0.0_dp) worst = max(worst, err_d/ref%distance)
      ! the returned points realise the returned distance, the normal is unit and joins them
      if (abs(norm2(fast%point_b - fast%point_a) - fast%distance) > 1.0e-13_dp*scale) n_geom_bad = n_geom_bad + 1
      if (abs(norm2(fast%normal) - 1.0_dp) > 1.0e-14_dp) n_geom_bad = n_geom_bad + 1
      if (fast%distance > 1.0e-9_dp*scale) then
        if (norm2(fast%point_b - fast%point_a - fast%distance*fast%normal) > 1.0e-12_dp*scale) &
          n_geom_bad = n_geom_bad + 1
      end if
    end do
    n_poses_total = n_poses_total + n
    call check(n_bad == 0, 'random poses '//meshes(ia)%source//' vs '//meshes(ib)%source//': tree = brute force')
    call check(n_geom_bad == 0, 'random poses '//meshes(ia)%source//' vs '//meshes(ib)%source// &
               ': points, normal consistent')
  end subroutine random_pairs

  !> Compare with brute force and with the hand-worked distance (tolerance 1e-13 relative:
  !> these inputs are exact to a few roundings, and rotations by pi/4 cost a few ulps).
  subroutine expect(ia, ib, xa, qa, xb, qb, expected, what)
    integer, intent(in) :: ia, ib
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4), expected
    character(len=*), intent(in) :: what
    type(distance_result_t) :: fast, ref
    call mesh_mesh_distance(trees(ia), xa, qa, trees(ib), xb, qb, fast)
    call mesh_mesh_distance_brute(meshes(ia), xa, qa, meshes(ib), xb, qb, ref)
    call check_close(fast%distance, expected, 1.0e-13_dp, what//': distance', atol=1.0e-14_dp)
    call check_close(fast%distance, ref%distance, 1.0e-13_dp, what//': equals brute force', atol=1.0e-14_dp)
    call check(abs(norm2(fast%normal) - 1.0_dp) < 1.0e-14_dp, what//': unit normal')
  end subroutine expect

  !> A face pointing at a node that does not exist is refused with the mesh and face named.
  subroutine bad_mesh()
    type(mesh_t) :: m
    type(skd_tree_t) :: t
    type(error_t) :: e
    call m%init(reshape([0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp, 1.0_dp, 0.0_dp], [3, 3]), &
                reshape([1, 2, 4], [3, 1]), 'broken.obj')
    call t%build(m, e)
    call check_error(e%code, e%message, [character(len=16) :: 'broken.obj', 'face 1', 'node 4'], &
                     'tree build refuses a face with a missing node')
  end subroutine bad_mesh

  subroutine contrived_cases()
    real(dp) :: q45(4), qv(4), qv_down(4), h, pi, gap
    type(distance_result_t) :: r
    pi = 4.0_dp*atan(1.0_dp)
    gap = 0.01_dp
    ! face on face, parallel: box (half height 0.2) above box, offset sideways
    call expect(1, 1, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [0.3_dp, 0.1_dp, 0.4_dp + gap], quat_identity, gap, &
                'face on face')
    ! exactly touching face on face
    call expect(1, 1, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [0.3_dp, 0.1_dp, 0.4_dp], quat_identity, 0.0_dp, &
                'face on face touching')
    ! box on the thin plate
    call expect(2, 1, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [0.1_dp, 0.0_dp, 0.22_dp + gap], quat_identity, gap, &
                'box over plate')
    ! edge on edge, parallel: both boxes turned 45 degrees about x, ridges along x
    q45 = axis_angle_quaternion([1.0_dp, 0.0_dp, 0.0_dp], 0.25_dp*pi)
    ! turned 45 degrees the corner (y, z) = (0.3, 0.2) of the section goes to
    ! ((0.3 - 0.2)/sqrt(2), (0.3 + 0.2)/sqrt(2)): A's top ridge; B's bottom ridge is the
    ! opposite corner, so B is shifted by 0.2/sqrt(2) in y to put the ridges one above the other
    h = 0.5_dp/sqrt(2.0_dp)
    call expect(1, 1, [0.0_dp, 0.0_dp, 0.0_dp], q45, [0.2_dp, 0.2_dp/sqrt(2.0_dp), 2.0_dp*h + gap], q45, gap, &
                'edge on edge parallel')
    ! vertex to vertex: A's corner (0.5, 0.3, 0.2) and B's corner (-0.5, -0.3, -0.2) on the line
    ! through both centres, rotated so the corners face each other along the diagonal
    call expect(1, 1, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, &
                [1.0_dp, 0.6_dp, 0.4_dp]*(1.0_dp + gap/norm2([1.0_dp, 0.6_dp, 0.4_dp])), quat_identity, gap, &
                'vertex to vertex')
    call expect(1, 1, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [1.0_dp, 0.6_dp, 0.4_dp], quat_identity, 0.0_dp, &
                'vertex touching vertex')
    call mesh_mesh_distance(trees(1), [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, trees(1), [1.0_dp, 0.6_dp, 0.4_dp], &
                            quat_identity, r)
    call check(abs(norm2(r%normal) - 1.0_dp) < 1.0e-14_dp, 'vertex touching vertex: a unit normal all the same')
    ! nested in a concavity: the small box (0.5 x 0.3 x 0.2 halves) in the L's inner corner
    ! (corner at (0.4, 0.4)), its -x face 0.01 from the L's x = 0.4 wall above y = 0.4, its
    ! -y face 0.02 from the y = 0.4 wall: distance 0.01
    call expect(5, 1, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [0.4_dp + 0.5_dp + 0.01_dp, 0.4_dp + 0.3_dp + 0.02_dp, &
                0.15_dp], quat_identity, 0.01_dp, 'box nested in the L corner')
    ! the blob inside the torus hole: compared with brute force (faceted: no closed form)
    call expect_brute(4, 3, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [0.0_dp, 0.0_dp, 0.05_dp], &
                      axis_angle_quaternion([1.0_dp, 2.0_dp, 3.0_dp], 0.7_dp), 'icosphere through torus hole')
    qv = axis_angle_quaternion([0.0_dp, 1.0_dp, 0.0_dp], 0.5_dp*pi)
    qv_down = qv
    call expect_brute(4, 4, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, [0.6_dp, 0.0_dp, 0.0_dp], qv_down, &
                      'interlocked tori (chain links)')
  end subroutine contrived_cases

  subroutine expect_brute(ia, ib, xa, qa, xb, qb, what)
    integer, intent(in) :: ia, ib
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4)
    character(len=*), intent(in) :: what
    type(distance_result_t) :: fast, ref
    call mesh_mesh_distance(trees(ia), xa, qa, trees(ib), xb, qb, fast)
    call mesh_mesh_distance_brute(meshes(ia), xa, qa, meshes(ib), xb, qb, ref)
    call check_close(fast%distance, ref%distance, 1.0e-12_dp, what//': equals brute force', atol=1.0e-14_dp)
    call check(fast%distance > 0.0_dp, what//': apart')
  end subroutine expect_brute

  subroutine sphere_cases()
    type(distance_result_t) :: r
    ! spheres: centres 5 apart, radii 1 and 2: gap 2 along +x (exact in binary)
    call sphere_sphere_distance([1.0_dp, 0.0_dp, 0.0_dp], 1.0_dp, [6.0_dp, 0.0_dp, 0.0_dp], 2.0_dp, r)
    call check_close(r%distance, 2.0_dp, 1.0e-15_dp, 'sphere-sphere distance')
    call check_close_array(r%point_a, [2.0_dp, 0.0_dp, 0.0_dp], 1.0e-15_dp, 'sphere-sphere point a')
    call check_close_array(r%point_b, [4.0_dp, 0.0_dp, 0.0_dp], 1.0e-15_dp, 'sphere-sphere point b')
    call sphere_sphere_distance([0.0_dp, 0.0_dp, 0.0_dp], 1.0_dp, [0.0_dp, 1.5_dp, 0.0_dp], 1.0_dp, r)
    call check_close(r%distance, -0.5_dp, 1.0e-15_dp, 'overlapping spheres: negative distance')
    ! sphere of radius 0.1 above the box top face (z = 0.2) at height 0.5: gap 0.2
    call sphere_mesh_distance([0.1_dp, 0.05_dp, 0.5_dp], 0.1_dp, trees(1), [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, r)
    call check_close(r%distance, 0.2_dp, 1.0e-14_dp, 'sphere over box face')
    call check_close_array(r%normal, [0.0_dp, 0.0_dp, -1.0_dp], 0.0_dp, 'sphere over box: normal from sphere to box', &
                           atol=1.0e-15_dp)
    call check_close_array(r%point_b, [0.1_dp, 0.05_dp, 0.2_dp], 1.0e-14_dp, 'sphere over box: point on box')
    ! sphere beyond the box corner (0.5, 0.3, 0.2) along (1, 1, 1): distance to the corner
    call sphere_mesh_distance([0.6_dp, 0.4_dp, 0.3_dp], 0.05_dp, trees(1), [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, r)
    call check_close(r%distance, sqrt(0.03_dp) - 0.05_dp, 1.0e-13_dp, 'sphere near box corner')
    ! posed box: turned about z by 90 degrees and moved; the sphere sees the rotated 0.3 half width
    call sphere_mesh_distance([2.0_dp, 0.0_dp, 0.0_dp], 0.5_dp, trees(1), [1.0_dp, 0.0_dp, 0.0_dp], &
                              axis_angle_quaternion([0.0_dp, 0.0_dp, 1.0_dp], 2.0_dp*atan(1.0_dp)), r)
    call check_close(r%distance, 0.2_dp, 1.0e-13_dp, 'sphere beside a turned box')
  end subroutine sphere_cases

  subroutine bound_and_pruning()
    type(distance_result_t) :: r, rb
    type(query_stats_t) :: stats, stats_brute
    type(mesh_t) :: big
    type(skd_tree_t) :: big_tree
    ! upper bound below the distance: nothing found; above: the same answer as without
    call mesh_mesh_distance(trees(3), [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, trees(4), [3.0_dp, 0.0_dp, 0.0_dp], &
                            quat_identity, r)
    call mesh_mesh_distance(trees(3), [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, trees(4), [3.0_dp, 0.0_dp, 0.0_dp], &
                            quat_identity, rb, upper_bound=0.5_dp*r%distance)
    call check(.not. rb%found, 'upper bound below the distance: not found')
    call mesh_mesh_distance(trees(3), [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, trees(4), [3.0_dp, 0.0_dp, 0.0_dp], &
                            quat_identity, rb, upper_bound=1.01_dp*r%distance)
    call check(rb%found .and. rb%distance == r%distance, 'upper bound above the distance: same answer')
    ! pruning works: two 1280-face icospheres 1 apart test under 1% of the brute-force pairs
    call icosphere_fixture(1.0_dp, 3, big)
    call big_tree%build(big, err)
    call mesh_mesh_distance(big_tree, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, big_tree, [3.0_dp, 0.1_dp, 0.0_dp], &
                            random_unit_quaternion(), r, stats)
    call mesh_mesh_distance_brute(big, [0.0_dp, 0.0_dp, 0.0_dp], quat_identity, big, [3.0_dp, 0.1_dp, 0.0_dp], &
                                  quat_identity, rb, stats_brute)
    call check(stats%primitive_tests*100_i8 < stats_brute%primitive_tests, 'pruning: under 1% of brute-force tests')
    call check(stats%box_pairs > 0_i8 .and. stats%leaf_pairs > 0_i8, 'statistics are counted')
  end subroutine bound_and_pruning

end program test_mesh_distance
