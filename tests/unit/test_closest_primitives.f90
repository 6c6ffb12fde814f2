!> Point-triangle and segment-segment closest points: hand-worked cases for every Voronoi
!> region, degenerate triangles, parallel / collinear / zero-length segments, and random
!> cases checked two independent ways: the optimality certificate of a projection onto a
!> convex set ((p - q).(x - q) <= 0 for every vertex x of the primitive) and dense sampling.
program test_closest_primitives
  use kinds, only: dp
  use closest_primitives
  use assertions
  implicit none
  real(dp) :: a(3), b(3), c(3), q(3), d2, s, t, c1(3), c2(3)
  integer :: region

  a = [0.0_dp, 0.0_dp, 0.0_dp]
  b = [1.0_dp, 0.0_dp, 0.0_dp]
  c = [0.0_dp, 1.0_dp, 0.0_dp]
  ! Hand-worked: each region of the unit right triangle. Exact arithmetic on these inputs
  ! (powers of two), so the tolerance is rounding of a few operations: 1e-15.
  call tri_case([-1.0_dp, -1.0_dp, 1.0_dp], a, REGION_VERTEX_A, 'vertex A')
  call tri_case([2.0_dp, -0.5_dp, 0.25_dp], b, REGION_VERTEX_B, 'vertex B')
  call tri_case([-0.5_dp, 2.0_dp, -1.0_dp], c, REGION_VERTEX_C, 'vertex C')
  call tri_case([0.5_dp, -1.0_dp, 2.0_dp], [0.5_dp, 0.0_dp, 0.0_dp], REGION_EDGE_AB, 'edge AB')
  call tri_case([1.0_dp, 1.0_dp, 1.0_dp], [0.5_dp, 0.5_dp, 0.0_dp], REGION_EDGE_BC, 'edge BC')
  call tri_case([-1.0_dp, 0.5_dp, 0.0_dp], [0.0_dp, 0.5_dp, 0.0_dp], REGION_EDGE_CA, 'edge CA')
  call tri_case([0.25_dp, 0.25_dp, 3.0_dp], [0.25_dp, 0.25_dp, 0.0_dp], REGION_FACE, 'face')
  call tri_case([0.25_dp, 0.25_dp, 0.0_dp], [0.25_dp, 0.25_dp, 0.0_dp], REGION_FACE, 'point on the face')

  ! Degenerate triangles: collinear and a single point.
  call closest_point_triangle([1.0_dp, 1.0_dp, 0.0_dp], a, b, 2.0_dp*b, q, region, d2)
  call check_close_array(q, [1.0_dp, 0.0_dp, 0.0_dp], 0.0_dp, 'collinear triangle: closest point', atol=1.0e-15_dp)
  call check_close(d2, 1.0_dp, 1.0e-15_dp, 'collinear triangle: distance')
  call closest_point_triangle([3.0_dp, 4.0_dp, 0.0_dp], b, b, b, q, region, d2)
  call check_close(d2, 20.0_dp, 1.0e-15_dp, 'point triangle: distance')

  ! Segments. Crossing at right angles, 2 apart.
  call closest_segment_segment([-1.0_dp, 0.0_dp, 0.0_dp], [1.0_dp, 0.0_dp, 0.0_dp], [0.0_dp, -1.0_dp, 2.0_dp], &
                               [0.0_dp, 1.0_dp, 2.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 4.0_dp, 1.0e-15_dp, 'crossing segments: distance')
  call check_close_array([s, t], [0.5_dp, 0.5_dp], 1.0e-15_dp, 'crossing segments: parameters')
  ! Parallel, overlapping in projection, 1 apart.
  call closest_segment_segment([0.0_dp, 0.0_dp, 0.0_dp], [2.0_dp, 0.0_dp, 0.0_dp], [1.0_dp, 1.0_dp, 0.0_dp], &
                               [3.0_dp, 1.0_dp, 0.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 1.0_dp, 1.0e-15_dp, 'parallel overlapping segments: distance')
  call check(s >= 0.5_dp - 1.0e-15_dp .and. abs(c1(1) - c2(1)) < 1.0e-15_dp, &
             'parallel overlapping segments: points face each other')
  ! Parallel, not overlapping: endpoint to endpoint, (2,0,0) to (3,1,0).
  call closest_segment_segment([0.0_dp, 0.0_dp, 0.0_dp], [2.0_dp, 0.0_dp, 0.0_dp], [3.0_dp, 1.0_dp, 0.0_dp], &
                               [5.0_dp, 1.0_dp, 0.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 2.0_dp, 1.0e-15_dp, 'parallel disjoint segments: distance')
  ! Collinear overlapping: distance 0; collinear disjoint: gap 1; antiparallel direction.
  call closest_segment_segment([0.0_dp, 0.0_dp, 0.0_dp], [2.0_dp, 0.0_dp, 0.0_dp], [3.0_dp, 0.0_dp, 0.0_dp], &
                               [1.0_dp, 0.0_dp, 0.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 0.0_dp, 0.0_dp, 'collinear overlapping segments: distance 0', atol=1.0e-30_dp)
  call closest_segment_segment([0.0_dp, 0.0_dp, 0.0_dp], [2.0_dp, 0.0_dp, 0.0_dp], [4.0_dp, 0.0_dp, 0.0_dp], &
                               [3.0_dp, 0.0_dp, 0.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 1.0_dp, 1.0e-15_dp, 'collinear disjoint segments: gap')
  call check_close_array([s, t], [1.0_dp, 1.0_dp], 0.0_dp, 'collinear disjoint segments: endpoints')
  ! Zero-length segments: point-segment and point-point.
  call closest_segment_segment([1.0_dp, 1.0_dp, 0.0_dp], [1.0_dp, 1.0_dp, 0.0_dp], [0.0_dp, 0.0_dp, 0.0_dp], &
                               [4.0_dp, 0.0_dp, 0.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 1.0_dp, 1.0e-15_dp, 'zero-length first segment')
  call check_close(t, 0.25_dp, 1.0e-15_dp, 'zero-length first segment: parameter')
  call closest_segment_segment([0.0_dp, 0.0_dp, 0.0_dp], [4.0_dp, 0.0_dp, 0.0_dp], [5.0_dp, 1.0_dp, 0.0_dp], &
                               [5.0_dp, 1.0_dp, 0.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 2.0_dp, 1.0e-15_dp, 'zero-length second segment')
  call closest_segment_segment([1.0_dp, 2.0_dp, 3.0_dp], [1.0_dp, 2.0_dp, 3.0_dp], [1.0_dp, 2.0_dp, 5.0_dp], &
                               [1.0_dp, 2.0_dp, 5.0_dp], s, t, c1, c2, d2)
  call check_close(d2, 4.0_dp, 1.0e-15_dp, 'two points')
  ! Nearly parallel crossing (angle 1e-9 rad, height 1e-3): distance 1e-3 at the crossing.
  call closest_segment_segment([-1.0_dp, -1.0e-9_dp, 0.0_dp], [1.0_dp, 1.0e-9_dp, 0.0_dp], [-1.0_dp, 1.0e-9_dp, 1.0e-3_dp], &
                               [1.0_dp, -1.0e-9_dp, 1.0e-3_dp], s, t, c1, c2, d2)
  ! the parallel branch is exact up to (angle*length)^2/4 = 1e-18 in d2: 1e-12 relative in d2
  call check_close(d2, 1.0e-6_dp, 1.0e-11_dp, 'nearly parallel crossing segments')

  call random_checks()
  call test_finish()

contains

  subroutine tri_case(point, expected, expected_region, what)
    real(dp), intent(in) :: point(3), expected(3)
    integer, intent(in) :: expected_region
    character(len=*), intent(in) :: what
    real(dp) :: closest(3), dist2
    integer :: reg
    call closest_point_triangle(point, a, b, c, closest, reg, dist2)
    call check_close_array(closest, expected, 0.0_dp, 'triangle '//what//': point', atol=1.0e-15_dp)
    call check(reg == expected_region, 'triangle '//what//': region')
    call check_close(dist2, sum((point - expected)**2), 1.0e-15_dp, 'triangle '//what//': distance', atol=1.0e-30_dp)
  end subroutine tri_case

  !> 20,000 random point-triangle and segment-segment cases (some made degenerate or
  !> parallel on purpose). Certificate tolerance: 1e-12 of the squared coordinate scale
  !> (inputs are O(1), rounding of the dot products is ~1e-15). Sampling (41 x 41 points on
  !> each primitive) may only be farther than the exact answer, never closer.
  subroutine random_checks()
    real(dp) :: r(12), x(3, 4), pt(3), cl(3), dd, worst_cert, u, v, e2, sample_min
    integer :: i, k, j, reg, n_cert_fail, n_sample_fail, kind
    n_cert_fail = 0
    n_sample_fail = 0
    worst_cert = 0.0_dp
    do i = 1, 10000
      call random_number(r)
      x = reshape(2.0_dp*r - 1.0_dp, [3, 4])
      kind = mod(i, 5)
      if (kind == 1) x(:, 3) = x(:, 1) + 0.3_dp*(x(:, 2) - x(:, 1))   ! collinear triangle
      if (kind == 2) x(:, 3) = x(:, 2)                                ! repeated vertex
      pt = 2.0_dp*x(:, 4)
      call closest_point_triangle(pt, x(:, 1), x(:, 2), x(:, 3), cl, reg, dd)
      do k = 1, 3
        u = dot_product(pt - cl, x(:, k) - cl)
        worst_cert = max(worst_cert, u)
        if (u > 1.0e-12_dp) n_cert_fail = n_cert_fail + 1
      end do
      sample_min = huge(1.0_dp)
      do k = 0, 40
        do j = 0, 40 - k
          u = k/40.0_dp
          v = j/40.0_dp
          sample_min = min(sample_min, sum((pt - (x(:, 1) + u*(x(:, 2) - x(:, 1)) + v*(x(:, 3) - x(:, 1))))**2))
        end do
      end do
      if (sample_min < dd - 1.0e-12_dp) n_sample_fail = n_sample_fail + 1
    end do
    call check(n_cert_fail == 0, 'random point-triangle: optimality certificate')
    call check(n_sample_fail == 0, 'random point-triangle: no sample closer than the answer')

    n_cert_fail = 0
    n_sample_fail = 0
    do i = 1, 10000
      call random_number(r)
      x = reshape(2.0_dp*r - 1.0_dp, [3, 4])
      kind = mod(i, 6)
      if (kind == 1) x(:, 4) = x(:, 3) + 0.7_dp*(x(:, 2) - x(:, 1))            ! parallel
      if (kind == 2) x(:, 3:4) = x(:, 1:2) + spread(0.5_dp*(x(:, 2) - x(:, 1)), 2, 2)  ! collinear
      if (kind == 3) x(:, 2) = x(:, 1)                                          ! zero length
      if (kind == 4) x(:, 4) = x(:, 3)
      call closest_segment_segment(x(:, 1), x(:, 2), x(:, 3), x(:, 4), s, t, c1, c2, dd)
      do k = 1, 2
        if (dot_product(c1 - c2, x(:, k) - c1) < -1.0e-12_dp) n_cert_fail = n_cert_fail + 1
        if (dot_product(c2 - c1, x(:, 2 + k) - c2) < -1.0e-12_dp) n_cert_fail = n_cert_fail + 1
      end do
      sample_min = huge(1.0_dp)
      do k = 0, 40
        do j = 0, 40
          e2 = sum((x(:, 1) + (k/40.0_dp)*(x(:, 2) - x(:, 1)) - x(:, 3) - (j/40.0_dp)*(x(:, 4) - x(:, 3)))**2)
          sample_min = min(sample_min, e2)
        end do
      end do
      if (sample_min < dd - 1.0e-12_dp) n_sample_fail = n_sample_fail + 1
      if (abs(sum((c1 - c2)**2) - dd) > 1.0e-15_dp) n_cert_fail = n_cert_fail + 1
    end do
    call check(n_cert_fail == 0, 'random segment-segment: optimality certificate')
    call check(n_sample_fail == 0, 'random segment-segment: no sample closer than the answer')
  end subroutine random_checks

end program test_closest_primitives
