!> A certified lower bound on the distance between two posed convex polytopes, and the
!> direction that realises it, by GJK (Gilbert, Johnson, Keerthi 1988; van den Bergen 1999)
!> on their vertices: what conservative advancement needs of each iterate, at a fraction of
!> the cost of the exact closest-point query (mesh_distance).
!>
!> Why a bound is enough, and why it is exact where it matters. For ANY unit n (from A to
!> B) the distance is at least the separation along n,
!>     sep(n) = min_{b in B} n.b - max_{a in A} n.a,
!> which for vertex sets is the two support points' difference: two passes over the
!> vertices. GJK builds the closest point v of the Minkowski difference A - B to the origin;
!> each iterate's support point w (the support of A - B against v) gives
!>     sep(-v/|v|) = v.w / |v|  <=  distance  <=  |v|,
!> so every iterate has a certified lower and upper bound, and for polytopes the two meet to
!> round-off in a few iterations (the last simplex holds the closest features). The routine
!> returns the largest lower bound seen and its direction: the gap it reports is exactly the
!> separation along the normal it reports (both computed from the same support points), which
!> is what advancement_bound's directional bound and turning_bound need (they bound how fast
!> the separation ALONG n can close, for any n). The conservative advancement of
!> time_of_contact takes these bounds for its iterates above the contact band and the exact
!> query (closest features, contact points) in the band, so no committed time of contact
!> depends on them: the times are the canonical crossings of the exact gap.
!>
!> Support points by brute force over the vertices (one rotation of the direction into
!> each body frame, then a dot product per vertex): meant for meshes with few vertices
!> (boxes: 8); callers fall back to the exact query above max_support_vertices.
!>
!> Round-off: sep is computed from world points each rounded once or twice (rotation and
!> translation), as the exact query's are, so both are "exact" to the same few ulps of the
!> positions.
module convex_distance
  use kinds, only: dp
  use quaternion, only: quat_to_matrix
  use closest_primitives, only: closest_point_triangle, REGION_VERTEX_A, REGION_VERTEX_B, REGION_VERTEX_C, &
                                REGION_EDGE_AB, REGION_EDGE_BC, REGION_EDGE_CA
  implicit none
  private
  public :: convex_bound_t, convex_lower_bound, max_support_vertices

  !> Larger meshes: the brute-force support costs more than the exact query saves.
  integer, parameter :: max_support_vertices = 64

  type :: convex_bound_t
    !> lower is a certified bound (> 0, the bodies are apart along normal)
    logical :: certified = .false.
    !> the separation along normal: a lower bound on the distance [m]
    real(dp) :: lower = 0.0_dp
    !> the distance of the closest simplex point: an upper bound on the distance [m]
    real(dp) :: upper = huge(1.0_dp)
    real(dp) :: normal(3) = 0.0_dp    !< unit, from A to B
    integer :: iterations = 0         !< support evaluations
  end type convex_bound_t

contains

  !> Lower bound on the distance between the convex hulls of nodes_a (body frame of A, posed
  !> at xa, qa: world = xa + R(qa) node) and nodes_b (posed at xb, qb). GJK until the lower
  !> and upper bounds agree to rel_tol (relative to the upper bound) or max_iterations
  !> support points. Not certified when the hulls touch or overlap (lower <= 0).
  pure subroutine convex_lower_bound(nodes_a, xa, qa, nodes_b, xb, qb, rel_tol, max_iterations, res)
    real(dp), intent(in) :: nodes_a(:, :), xa(3), qa(4), nodes_b(:, :), xb(3), qb(4)
    real(dp), intent(in) :: rel_tol
    integer, intent(in) :: max_iterations
    type(convex_bound_t), intent(out) :: res
    real(dp) :: ra(3, 3), rb(3, 3), simplex(3, 4), v(3), w(3), vv, vw, lower, v_new(3)
    integer :: n, k
    logical :: overlap
    ra = quat_to_matrix(qa)
    rb = quat_to_matrix(qb)
    ! any point of A - B to start: the difference of the first vertices
    v = support(nodes_a, ra, xa, [0.0_dp, 0.0_dp, 0.0_dp], .true.) - &
        support(nodes_b, rb, xb, [0.0_dp, 0.0_dp, 0.0_dp], .true.)
    n = 0
    do k = 1, max_iterations
      vv = dot_product(v, v)
      if (vv <= 0.0_dp) exit                       ! touching: not certified
      ! support of A - B against v: A's farthest point along -v, B's along +v
      w = support(nodes_a, ra, xa, -v, .false.) - support(nodes_b, rb, xb, v, .false.)
      res%iterations = k
      vw = dot_product(v, w)
      lower = vw/sqrt(vv)
      if (lower > res%lower) then
        res%lower = lower
        res%normal = -v/sqrt(vv)
      end if
      res%upper = min(res%upper, sqrt(vv))
      ! converged: the bounds agree (also catches w already in the simplex)
      if (res%upper - res%lower <= rel_tol*res%upper) exit
      if (in_simplex(w)) exit
      n = n + 1
      simplex(:, n) = w
      call closest_on_simplex(simplex, n, v_new, overlap)
      if (overlap) exit
      ! no progress: round-off has the last word (the first v was any point of A - B,
      ! not the closest of a simplex, so the test starts with the second)
      if (k > 1 .and. dot_product(v_new, v_new) >= vv) exit
      v = v_new
    end do
    res%certified = res%lower > 0.0_dp
    if (.not. res%certified) res%lower = 0.0_dp
  contains
    pure logical function in_simplex(p)
      real(dp), intent(in) :: p(3)
      integer :: m
      in_simplex = .false.
      do m = 1, n
        if (all(simplex(:, m) == p)) in_simplex = .true.
      end do
    end function in_simplex
  end subroutine convex_lower_bound

  !> The world point of the vertex farthest along d (first vertex if `first`).
  pure function support(nodes, r, x, d, first) result(p)
    real(dp), intent(in) :: nodes(:, :), r(3, 3), x(3), d(3)
    logical, intent(in) :: first
    real(dp) :: p(3), d_body(3), best, s
    integer :: k, kb
    kb = 1
    if (.not. first) then
      d_body = matmul(d, r)                  ! R^T d: the direction in the body frame
      best = -huge(1.0_dp)
      do k = 1, size(nodes, 2)
        s = d_body(1)*nodes(1, k) + d_body(2)*nodes(2, k) + d_body(3)*nodes(3, k)
        if (s > best) then
          best = s
          kb = k
        end if
      end do
    end if
    p = x + matmul(r, nodes(:, kb))
  end function support

  !> The point of the simplex (1 to 4 points) closest to the origin; the simplex is reduced
  !> to the points whose Voronoi feature holds it (Ericson, Real-Time Collision Detection,
  !> 5.1). overlap: the origin lies inside a tetrahedron (the hulls intersect).
  pure subroutine closest_on_simplex(s, n, v, overlap)
    real(dp), intent(inout) :: s(3, 4)
    integer, intent(inout) :: n
    real(dp), intent(out) :: v(3)
    logical, intent(out) :: overlap
    real(dp), parameter :: origin(3) = 0.0_dp
    real(dp) :: t, e(3), ee, best, d2, c(3), sub(3, 3), vol, side, opposite, normal_f(3)
    integer :: region, f, best_face, best_keep(3), best_n
    integer, parameter :: faces(3, 4) = reshape([2, 3, 4, 1, 3, 4, 1, 2, 4, 1, 2, 3], [3, 4])
    overlap = .false.
    select case (n)
    case (1)
      v = s(:, 1)
    case (2)
      e = s(:, 2) - s(:, 1)
      ee = dot_product(e, e)
      t = 0.0_dp
      if (ee > 0.0_dp) t = -dot_product(s(:, 1), e)/ee
      if (t <= 0.0_dp) then
        n = 1
        v = s(:, 1)
      else if (t >= 1.0_dp) then
        s(:, 1) = s(:, 2)
        n = 1
        v = s(:, 1)
      else
        v = s(:, 1) + t*e
      end if
    case (3)
      call closest_point_triangle(origin, s(:, 1), s(:, 2), s(:, 3), v, region, d2)
      call reduce_triangle(s, n, region)
    case (4)
      ! the origin on the outer side of a face (or the tetrahedron flat): that face's
      ! closest point; none: inside
      vol = dot_product(s(:, 2) - s(:, 1), cross(s(:, 3) - s(:, 1), s(:, 4) - s(:, 1)))
      best = huge(1.0_dp)
      best_face = 0
      best_n = 0
      do f = 1, 4
        sub = s(:, faces(:, f))
        ! the origin on the opposite vertex's side of face f (vertex f is not on it): skip
        normal_f = cross(sub(:, 2) - sub(:, 1), sub(:, 3) - sub(:, 1))
        side = dot_product(origin - sub(:, 1), normal_f)
        opposite = dot_product(s(:, f) - sub(:, 1), normal_f)
        if (vol /= 0.0_dp .and. side*opposite > 0.0_dp) cycle
        call closest_point_triangle(origin, sub(:, 1), sub(:, 2), sub(:, 3), c, region, d2)
        if (d2 < best) then
          best = d2
          best_face = f
          v = c
          call region_points(region, faces(:, f), best_n, best_keep)
        end if
      end do
      if (best_face == 0) then
        overlap = .true.
        v = 0.0_dp
        return
      end if
      sub(:, 1:best_n) = s(:, best_keep(1:best_n))
      s(:, 1:best_n) = sub(:, 1:best_n)
      n = best_n
    end select
  end subroutine closest_on_simplex

  !> Keeps the triangle's points of the Voronoi region that holds the closest point.
  pure subroutine reduce_triangle(s, n, region)
    real(dp), intent(inout) :: s(3, 4)
    integer, intent(inout) :: n
    integer, intent(in) :: region
    integer :: keep(3), m
    real(dp) :: kept(3, 3)
    call region_points(region, [1, 2, 3], m, keep)
    kept(:, 1:m) = s(:, keep(1:m))
    s(:, 1:m) = kept(:, 1:m)
    n = m
  end subroutine reduce_triangle

  !> The points (of ids(1:3), a triangle) of a Voronoi region of closest_point_triangle.
  pure subroutine region_points(region, ids, m, kept)
    integer, intent(in) :: region, ids(3)
    integer, intent(out) :: m, kept(3)
    kept = ids
    select case (region)
    case (REGION_VERTEX_A)
      m = 1
      kept(1) = ids(1)
    case (REGION_VERTEX_B)
      m = 1
      kept(1) = ids(2)
    case (REGION_VERTEX_C)
      m = 1
      kept(1) = ids(3)
    case (REGION_EDGE_AB)
      m = 2
      kept(1:2) = [ids(1), ids(2)]
    case (REGION_EDGE_BC)
      m = 2
      kept(1:2) = [ids(2), ids(3)]
    case (REGION_EDGE_CA)
      m = 2
      kept(1:2) = [ids(3), ids(1)]
    case default
      m = 3
    end select
  end subroutine region_points

  pure function cross(a, b) result(c)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: c(3)
    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross

end module convex_distance
