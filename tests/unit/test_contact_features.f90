!> Contact feature sets against hand counts (box face down on a box: 4, with two corners on
!> the diagonal of the lower face still 4; edge on a face: 2; vertex on a face: 1; a tilted
!> box on a plate: 2, or 4 when the tolerance covers the tilt; crossed edges: 1) and the
!> overlap test (disjoint, crossing, touching, nested, interlocked, random poses).
program test_contact_features
  use kinds, only: dp
  use mesh, only: mesh_t
  use error_status, only: error_t
  use skd_tree, only: skd_tree_t
  use mesh_distance
  use contact_features
  use quaternion, only: quat_identity
  use mesh_fixtures
  use assertions
  implicit none
  type(mesh_t) :: cube, slab, plate, brick, ico, torus, big
  type(skd_tree_t) :: t_cube, t_slab, t_plate, t_brick, t_ico, t_torus, t_big
  type(error_t) :: err
  type(contact_feature_t), allocatable :: features(:)
  integer :: n
  real(dp) :: pi, gap, s2, s3, qv(4), tilt
  real(dp), parameter :: origin(3) = 0.0_dp

  pi = 4.0_dp*atan(1.0_dp)
  s2 = sqrt(2.0_dp)
  s3 = sqrt(3.0_dp)
  call box_fixture([0.2_dp, 0.2_dp, 0.2_dp], cube)
  call box_fixture([1.0_dp, 1.0_dp, 0.2_dp], slab)
  call box_fixture([1.0_dp, 1.0_dp, 0.02_dp], plate)
  call box_fixture([0.3_dp, 0.2_dp, 0.1_dp], brick)
  call icosphere_fixture(0.3_dp, 2, ico)
  call torus_fixture(0.6_dp, 0.2_dp, 16, 8, torus)
  call box_fixture([2.0_dp, 2.0_dp, 2.0_dp], big)
  call t_cube%build(cube, err)
  call t_slab%build(slab, err)
  call t_plate%build(plate, err)
  call t_brick%build(brick, err)
  call t_ico%build(ico, err)
  call t_torus%build(torus, err)
  call t_big%build(big, err)
  call check(err%ok(), 'trees build')
  gap = 1.0e-4_dp

  ! Box face down on a box, corners away from the lower face's diagonal: 4 vertex-face.
  call find_contact_features(t_cube, [0.1_dp, 0.05_dp, 0.4_dp + gap], quat_identity, t_slab, origin, quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 4, 'box face down on a box: 4 features')
  call check(all(features(1:n)%kind == FEATURE_VERTEX_FACE), 'box face down: all vertex-face')
  call check_normals(features, n, [0.0_dp, 0.0_dp, -1.0_dp], gap, 'box face down')
  ! Same, cube centred: two of its corners lie on the diagonal shared by the slab's two top
  ! triangles, each found against both and kept once.
  call find_contact_features(t_cube, [0.0_dp, 0.0_dp, 0.4_dp + gap], quat_identity, t_slab, origin, quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 4, 'box face down, corners on the shared diagonal: 4 features')
  ! A search far wider than the gap (speculative contacts look as far as the step can reach)
  ! finds each corner against the triangle it lies over, and not again against the
  ! neighbouring triangle across the flat diagonal (a point on that edge, up to 11 cm away,
  ! with a normal tilted towards it: before the filter a block sliding on an incline was
  ! pushed sideways by such a feature).
  call find_contact_features(t_cube, [0.1_dp, 0.05_dp, 0.4_dp + gap], quat_identity, t_slab, origin, quat_identity, &
                             0.15_dp, features, n)
  call check(n == 4, 'box face down, wide search: still 4 features')
  call check_normals(features, n, [0.0_dp, 0.0_dp, -1.0_dp], gap, 'box face down, wide search')
  ! The other way round (slab is A): 4 face-vertex features, normal +z from A to B.
  call find_contact_features(t_slab, origin, quat_identity, t_cube, [0.1_dp, 0.05_dp, 0.4_dp + gap], quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 4 .and. all(features(1:n)%kind == FEATURE_FACE_VERTEX), 'slab under a box: 4 face-vertex')
  call check_normals(features, n, [0.0_dp, 0.0_dp, 1.0_dp], gap, 'slab under a box')
  ! Exactly touching (gap 0), same-size faces stacked exactly: each corner of the upper
  ! cube is also a corner of the lower one, found from both sides, kept once: 4.
  call find_contact_features(t_cube, [0.0_dp, 0.0_dp, 0.4_dp], quat_identity, t_cube, origin, quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 4, 'equal cubes stacked exactly: 4 features')

  ! Edge on a face: cube turned 45 degrees about x, lowest edge 0.2 sqrt(2) below its centre.
  qv = axis_angle_quaternion([1.0_dp, 0.0_dp, 0.0_dp], 0.25_dp*pi)
  call find_contact_features(t_cube, [0.1_dp, 0.0_dp, 0.2_dp + 0.2_dp*s2 + gap], qv, t_slab, origin, quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 2, 'edge on a face: 2 features')
  call check_normals(features, n, [0.0_dp, 0.0_dp, -1.0_dp], gap, 'edge on a face')

  ! Vertex on a face: the cube's corner (-1,-1,-1) turned to point straight down.
  qv = rotation_between([-1.0_dp, -1.0_dp, -1.0_dp]/s3, [0.0_dp, 0.0_dp, -1.0_dp])
  call find_contact_features(t_cube, [0.1_dp, -0.2_dp, 0.2_dp + 0.2_dp*s3 + gap], qv, t_slab, origin, quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 1, 'vertex on a face: 1 feature')
  call check_normals(features, n, [0.0_dp, 0.0_dp, -1.0_dp], gap, 'vertex on a face')

  ! Tilted brick on a thin plate: tilt 0.1 rad about y, resting on its x = +0.3 bottom edge,
  ! the other bottom edge lifted by 0.6 sin(0.1) = 0.06: 2 features at tolerance 1e-3.
  tilt = 0.1_dp
  qv = axis_angle_quaternion([0.0_dp, 1.0_dp, 0.0_dp], tilt)
  call find_contact_features(t_brick, [0.0_dp, 0.0_dp, 0.02_dp + 0.3_dp*sin(tilt) + 0.1_dp*cos(tilt) + gap], qv, &
                             t_plate, origin, quat_identity, 1.0e-3_dp, features, n)
  call check(n == 2, 'tilted box on a plate: 2 features')
  call check_normals(features, n, [0.0_dp, 0.0_dp, -1.0_dp], gap, 'tilted box on a plate')
  ! Tilt 1e-4 rad: the lifted edge is 6e-5 up, inside a 1e-3 tolerance: all 4 corners.
  tilt = 1.0e-4_dp
  qv = axis_angle_quaternion([0.0_dp, 1.0_dp, 0.0_dp], tilt)
  call find_contact_features(t_brick, [0.0_dp, 0.0_dp, 0.02_dp + 0.3_dp*sin(tilt) + 0.1_dp*cos(tilt) + gap], qv, &
                             t_plate, origin, quat_identity, 1.0e-3_dp, features, n)
  call check(n == 4, 'slightly tilted box on a plate: 4 features')

  ! Crossed ridges: cube turned about x above a cube turned about y, 1 edge-edge feature.
  call find_contact_features(t_cube, [0.0_dp, 0.0_dp, 0.4_dp*s2 + gap], &
                             axis_angle_quaternion([1.0_dp, 0.0_dp, 0.0_dp], 0.25_dp*pi), &
                             t_cube, origin, axis_angle_quaternion([0.0_dp, 1.0_dp, 0.0_dp], 0.25_dp*pi), &
                             1.0e-3_dp, features, n)
  call check(n == 1, 'crossed edges: 1 feature')
  if (n >= 1) then
    call check(features(1)%kind == FEATURE_EDGE_EDGE, 'crossed edges: edge-edge')
    call check_normals(features, n, [0.0_dp, 0.0_dp, -1.0_dp], gap, 'crossed edges')
  end if
  ! Far apart: nothing.
  call find_contact_features(t_cube, [0.0_dp, 0.0_dp, 1.0_dp], quat_identity, t_slab, origin, quat_identity, &
                             1.0e-3_dp, features, n)
  call check(n == 0, 'far apart: no features')

  call random_feature_sets()
  call overlap_cases()
  call test_finish()

contains

  !> Normals equal the expected direction and distances the gap (1e-12: rotations by pi/4
  !> and the gap 1e-4 on coordinates O(1) leave rounding ~1e-16 / 1e-4).
  subroutine check_normals(f, count, expected, distance, what)
    type(contact_feature_t), intent(in) :: f(:)
    integer, intent(in) :: count
    real(dp), intent(in) :: expected(3), distance
    character(len=*), intent(in) :: what
    integer :: k
    do k = 1, count
      call check_close_array(f(k)%normal, expected, 0.0_dp, what//': normal', atol=1.0e-12_dp)
      call check_close(f(k)%distance, distance, 1.0e-10_dp, what//': distance')
      call check_close_array(f(k)%point_b - f(k)%point_a, distance*expected, 0.0_dp, what//': points', atol=1.0e-13_dp)
    end do
  end subroutine check_normals

  function rotation_between(a, b) result(q)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: q(4), axis(3)
    axis = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
    q = axis_angle_quaternion(axis, acos(dot_product(a, b)))
  end function rotation_between

  !> Random poses of a blob against a torus, tolerance their distance plus 2 cm: every
  !> feature is within the tolerance and its points are that far apart (1e-12 of the size:
  !> rounding), and the closest feature is the closest-point distance (1e-12 relative, as
  !> both come from the same primitive formulas; the minimum of a surface pair is always
  !> reached at a vertex-face pair or an interior crossing of two creases).
  subroutine random_feature_sets()
    type(mesh_t) :: blob
    type(skd_tree_t) :: t_blob
    type(distance_result_t) :: r
    real(dp) :: qa(4), qb(4), xb(3), u, tol, dmin
    integer :: k, j, n_bad_min, n_bad_feature, n_total, n_apart
    call blob_fixture(0.4_dp, 2, 0.3_dp, [0.5_dp, 1.5_dp, 2.5_dp], blob)
    call t_blob%build(blob, err)
    n_bad_min = 0
    n_bad_feature = 0
    n_total = 0
    n_apart = 0
    do k = 1, 300
      qa = random_unit_quaternion()
      qb = random_unit_quaternion()
      call random_number(u)
      xb = (0.9_dp + 1.0_dp*u)*random_unit_vector()
      ! crossing surfaces have no meaningful distance (see mesh_distance): skip them
      if (bodies_overlap(t_blob, origin, qa, t_torus, xb, qb)) cycle
      n_apart = n_apart + 1
      call mesh_mesh_distance(t_blob, origin, qa, t_torus, xb, qb, r)
      tol = r%distance + 0.02_dp
      call find_contact_features(t_blob, origin, qa, t_torus, xb, qb, tol, features, n)
      n_total = n_total + n
      dmin = huge(1.0_dp)
      do j = 1, n
        dmin = min(dmin, features(j)%distance)
        if (features(j)%distance > tol .or. abs(norm2(features(j)%point_b - features(j)%point_a) - &
                                                 features(j)%distance) > 1.0e-12_dp) n_bad_feature = n_bad_feature + 1
        if (abs(norm2(features(j)%normal) - 1.0_dp) > 1.0e-12_dp) n_bad_feature = n_bad_feature + 1
      end do
      if (abs(dmin - r%distance) > 1.0e-12_dp*r%distance) n_bad_min = n_bad_min + 1
    end do
    call check(n_bad_feature == 0, 'random feature sets: each feature within tolerance, consistent')
    call check(n_bad_min == 0, 'random feature sets: the closest feature is the distance')
    call check(n_total > 300 .and. n_apart > 200, 'random feature sets: enough poses and features')
  end subroutine random_feature_sets

  subroutine overlap_cases()
    type(distance_result_t) :: r
    real(dp) :: xb(3), qa(4), qb(4), dcent, r_in, r_out
    integer :: k, n_wrong, n_sure
    call check(.not. bodies_overlap(t_cube, origin, quat_identity, t_cube, [0.0_dp, 0.0_dp, 0.41_dp], quat_identity), &
               'separated cubes do not overlap')
    call check(bodies_overlap(t_cube, origin, quat_identity, t_cube, [0.2_dp, 0.0_dp, 0.0_dp], quat_identity), &
               'cubes offset by half a side overlap')
    call check(bodies_overlap(t_cube, origin, quat_identity, t_cube, [0.0_dp, 0.0_dp, 0.4_dp], quat_identity), &
               'cubes touching face to face count as overlapping')
    call check(bodies_overlap(t_cube, [0.3_dp, 0.1_dp, -0.2_dp], random_unit_quaternion(), t_big, origin, quat_identity), &
               'cube inside a big box overlaps')
    call check(bodies_overlap(t_big, origin, quat_identity, t_cube, [0.3_dp, 0.1_dp, -0.2_dp], random_unit_quaternion()), &
               'big box around a cube overlaps')
    call check(.not. bodies_overlap(t_torus, origin, quat_identity, t_ico, [0.0_dp, 0.0_dp, 0.05_dp], quat_identity), &
               'sphere in the torus hole does not overlap')
    qv = axis_angle_quaternion([1.0_dp, 0.0_dp, 0.0_dp], 0.5_dp*pi)
    call check(.not. bodies_overlap(t_torus, origin, quat_identity, t_torus, [0.6_dp, 0.0_dp, 0.0_dp], qv), &
               'interlocked tori do not overlap')
    call check(bodies_overlap(t_torus, origin, quat_identity, t_torus, [0.9_dp, 0.0_dp, 0.0_dp], qv), &
               'interlocked tori pushed into each other overlap')
    call check(bodies_overlap(t_plate, origin, quat_identity, t_plate, [0.0_dp, 0.0_dp, 0.0_dp], &
                              axis_angle_quaternion([1.0_dp, 0.0_dp, 0.0_dp], 0.5_dp*pi)), &
               'crossed plates (no vertex inside the other) overlap')
    call check_no_overlap(t_cube, origin, quat_identity, "1 'left'", t_cube, [0.2_dp, 0.0_dp, 0.0_dp], &
                          quat_identity, "2 'right'", err)
    call check_error(err%code, err%message, [character(len=16) :: "1 'left'", "2 'right'", 'overlap'], &
                     'overlap error names both bodies')
    ! Random poses of two 320-face icospheres (radius 0.3; inscribed radius of the faceted
    ! sphere > 0.29): centres under 2 x 0.29 apart must overlap, over 0.6 apart must not,
    ! and whenever bodies_overlap is false the distance is positive.
    r_out = 0.3_dp
    r_in = 0.29_dp
    n_wrong = 0
    n_sure = 0
    do k = 1, 400
      qa = random_unit_quaternion()
      qb = random_unit_quaternion()
      call random_number(dcent)
      dcent = 0.8_dp*dcent
      xb = dcent*random_unit_vector()
      if (dcent < 2.0_dp*r_in) then
        n_sure = n_sure + 1
        if (.not. bodies_overlap(t_ico, origin, qa, t_ico, xb, qb)) n_wrong = n_wrong + 1
      else if (dcent > 2.0_dp*r_out) then
        n_sure = n_sure + 1
        if (bodies_overlap(t_ico, origin, qa, t_ico, xb, qb)) n_wrong = n_wrong + 1
      else if (.not. bodies_overlap(t_ico, origin, qa, t_ico, xb, qb)) then
        call mesh_mesh_distance(t_ico, origin, qa, t_ico, xb, qb, r)
        if (r%distance <= 0.0_dp) n_wrong = n_wrong + 1
      end if
    end do
    call check(n_wrong == 0 .and. n_sure > 300, 'random icosphere poses: overlap agrees with the geometry')
  end subroutine overlap_cases

end program test_contact_features
