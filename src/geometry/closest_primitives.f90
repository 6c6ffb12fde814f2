!> Exact closest points between the primitives of triangle meshes: point-segment,
!> point-triangle (Ericson, Real-Time Collision Detection 5.1.5, Voronoi-region method) and
!> segment-segment (Ericson 5.1.9, with parallel and zero-length segments handled apart).
!> All routines return the squared distance as well, so callers compare squared values and
!> take one square root at the end. Every routine is robust for degenerate input (zero-area
!> triangles, zero-length segments): it always returns a point that lies on the primitive.
module closest_primitives
  use kinds, only: dp
  implicit none
  private
  public :: closest_point_segment, closest_point_triangle, closest_segment_segment
  public :: REGION_VERTEX_A, REGION_VERTEX_B, REGION_VERTEX_C, REGION_EDGE_AB, REGION_EDGE_BC, &
            REGION_EDGE_CA, REGION_FACE

  !> Voronoi region of the triangle (a, b, c) holding the closest point.
  integer, parameter :: REGION_VERTEX_A = 1
  integer, parameter :: REGION_VERTEX_B = 2
  integer, parameter :: REGION_VERTEX_C = 3
  integer, parameter :: REGION_EDGE_AB = 4
  integer, parameter :: REGION_EDGE_BC = 5
  integer, parameter :: REGION_EDGE_CA = 6
  integer, parameter :: REGION_FACE = 7

  !> Squared length below which a segment is treated as a point [m^2]: far below any mesh
  !> feature, and large enough that dividing by it cannot overflow.
  real(dp), parameter :: zero_length2 = 1.0e-300_dp
  !> sin^2 of the angle below which two segments are treated as parallel. Below it the
  !> interior formula loses accuracy (error in s ~ eps/sin^2); the endpoint candidates used
  !> instead are exact for parallel segments and off by at most (angle*length)^2/4 ~ 1e-16
  !> length^2 in the squared distance otherwise, i.e. at rounding level.
  real(dp), parameter :: parallel_sin2 = 1.0e-16_dp
  !> sin^2 of a triangle's angle below which it is a sliver whose Voronoi regions cannot be
  !> decided reliably in floating point (the region quantities are then mostly rounding).
  real(dp), parameter :: sliver_sin2 = 1.0e-10_dp

contains

  !> Closest point c = a + t (b - a), t in [0, 1], of segment ab to p; dist2 = |p - c|^2.
  pure subroutine closest_point_segment(p, a, b, t, closest, dist2)
    real(dp), intent(in) :: p(3), a(3), b(3)
    real(dp), intent(out) :: t, closest(3), dist2
    real(dp) :: d(3), len2
    d = b - a
    len2 = d(1)*d(1) + d(2)*d(2) + d(3)*d(3)
    if (len2 <= zero_length2) then
      t = 0.0_dp
    else
      t = min(1.0_dp, max(0.0_dp, ((p(1) - a(1))*d(1) + (p(2) - a(2))*d(2) + (p(3) - a(3))*d(3))/len2))
    end if
    closest = a + t*d
    d = p - closest
    dist2 = d(1)*d(1) + d(2)*d(2) + d(3)*d(3)
  end subroutine closest_point_segment

  !> Closest point of triangle (a, b, c) to p, the Voronoi region it lies in, and the squared
  !> distance. Ericson's region tests use only dot products of edge vectors, so each region
  !> is decided consistently; divisions are guarded, and a zero-area triangle reaching the
  !> face branch falls back to the closest of its three edges.
  pure subroutine closest_point_triangle(p, a, b, c, closest, region, dist2)
    real(dp), intent(in) :: p(3), a(3), b(3), c(3)
    real(dp), intent(out) :: closest(3)
    integer, intent(out) :: region
    real(dp), intent(out) :: dist2
    real(dp) :: ab(3), ac(3), ap(3), bp(3), cp(3)
    real(dp) :: d1, d2, d3, d4, d5, d6, va, vb, vc, v, w, denom, t, e2, q(3)
    ab = b - a
    ac = c - a
    ap = p - a
    d1 = dot3(ab, ap)
    d2 = dot3(ac, ap)
    if (d1 <= 0.0_dp .and. d2 <= 0.0_dp) then
      closest = a
      region = REGION_VERTEX_A
      dist2 = sqdist(p, closest)
      return
    end if
    bp = p - b
    d3 = dot3(ab, bp)
    d4 = dot3(ac, bp)
    if (d3 >= 0.0_dp .and. d4 <= d3) then
      closest = b
      region = REGION_VERTEX_B
      dist2 = sqdist(p, closest)
      return
    end if
    vc = d1*d4 - d3*d2
    if (vc <= 0.0_dp .and. d1 >= 0.0_dp .and. d3 <= 0.0_dp) then
      ! d1 - d3 = |ab|^2 >= 0
      denom = d1 - d3
      v = 0.0_dp
      if (denom > 0.0_dp) v = min(1.0_dp, d1/denom)
      closest = a + v*ab
      region = REGION_EDGE_AB
      dist2 = sqdist(p, closest)
      return
    end if
    cp = p - c
    d5 = dot3(ab, cp)
    d6 = dot3(ac, cp)
    if (d6 >= 0.0_dp .and. d5 <= d6) then
      closest = c
      region = REGION_VERTEX_C
      dist2 = sqdist(p, closest)
      return
    end if
    vb = d5*d2 - d1*d6
    if (vb <= 0.0_dp .and. d2 >= 0.0_dp .and. d6 <= 0.0_dp) then
      denom = d2 - d6          ! = |ac|^2
      w = 0.0_dp
      if (denom > 0.0_dp) w = min(1.0_dp, d2/denom)
      closest = a + w*ac
      region = REGION_EDGE_CA
      dist2 = sqdist(p, closest)
      return
    end if
    va = d3*d6 - d5*d4
    if (va <= 0.0_dp .and. (d4 - d3) >= 0.0_dp .and. (d5 - d6) >= 0.0_dp) then
      denom = (d4 - d3) + (d5 - d6)   ! = |bc|^2
      w = 0.0_dp
      if (denom > 0.0_dp) w = min(1.0_dp, (d4 - d3)/denom)
      closest = b + w*(c - b)
      region = REGION_EDGE_BC
      dist2 = sqdist(p, closest)
      return
    end if
    denom = va + vb + vc               ! = |ab x ac|^2 = |ab|^2 |ac|^2 sin^2(angle at a)
    if (denom > sliver_sin2*dot3(ab, ab)*dot3(ac, ac)) then
      v = vb/denom
      w = vc/denom
      closest = a + v*ab + w*ac
      region = REGION_FACE
      dist2 = sqdist(p, closest)
      return
    end if
    ! Zero-area or sliver triangle: the region tests above are decided by rounding noise.
    ! Its points are (nearly) those of its edges; the clamped face point is a candidate
    ! too, and every candidate lies on the triangle, so the best is never too close.
    call closest_point_segment(p, a, b, t, closest, dist2)
    region = REGION_EDGE_AB
    call closest_point_segment(p, b, c, t, q, e2)
    if (e2 < dist2) then
      closest = q; dist2 = e2; region = REGION_EDGE_BC
    end if
    call closest_point_segment(p, c, a, t, q, e2)
    if (e2 < dist2) then
      closest = q; dist2 = e2; region = REGION_EDGE_CA
    end if
    if (denom >= tiny(1.0_dp)) then
      v = max(0.0_dp, vb/denom)
      w = max(0.0_dp, vc/denom)
      if (v + w > 1.0_dp) then
        v = v/(v + w)
        w = 1.0_dp - v
      end if
      q = a + v*ab + w*ac
      e2 = sqdist(p, q)
      if (e2 < dist2) then
        closest = q; dist2 = e2; region = REGION_FACE
      end if
    end if
  end subroutine closest_point_triangle

  !> Closest points c1 = p1 + s (q1 - p1) and c2 = p2 + t (q2 - p2), s, t in [0, 1], of two
  !> segments, and dist2 = |c1 - c2|^2. Zero-length segments reduce to point-segment; (nearly)
  !> parallel segments take the best of the four endpoint-to-segment candidates, which is
  !> exact for parallel segments (their distance is always reached at an endpoint).
  pure subroutine closest_segment_segment(p1, q1, p2, q2, s, t, c1, c2, dist2)
    real(dp), intent(in) :: p1(3), q1(3), p2(3), q2(3)
    real(dp), intent(out) :: s, t, c1(3), c2(3), dist2
    real(dp) :: d1(3), d2(3), r(3), a, b, c, e, f, denom, u, x(3), e2, diff(3)
    d1 = q1 - p1
    d2 = q2 - p2
    r = p1 - p2
    a = dot3(d1, d1)
    e = dot3(d2, d2)
    f = dot3(d2, r)
    if (a <= zero_length2 .and. e <= zero_length2) then
      s = 0.0_dp
      t = 0.0_dp
    else if (a <= zero_length2) then
      s = 0.0_dp
      t = min(1.0_dp, max(0.0_dp, f/e))
    else
      c = dot3(d1, r)
      if (e <= zero_length2) then
        t = 0.0_dp
        s = min(1.0_dp, max(0.0_dp, -c/a))
      else
        b = dot3(d1, d2)
        denom = a*e - b*b
        if (denom > parallel_sin2*a*e) then
          s = min(1.0_dp, max(0.0_dp, (b*f - c*e)/denom))
          t = (b*s + f)/e
          if (t < 0.0_dp) then
            t = 0.0_dp
            s = min(1.0_dp, max(0.0_dp, -c/a))
          else if (t > 1.0_dp) then
            t = 1.0_dp
            s = min(1.0_dp, max(0.0_dp, (b - c)/a))
          end if
        else
          ! Parallel: the four endpoint candidates, best kept.
          call closest_point_segment(p1, p2, q2, t, c2, dist2)
          s = 0.0_dp
          call closest_point_segment(q1, p2, q2, u, x, e2)
          if (e2 < dist2) then
            dist2 = e2; s = 1.0_dp; t = u
          end if
          call closest_point_segment(p2, p1, q1, u, x, e2)
          if (e2 < dist2) then
            dist2 = e2; s = u; t = 0.0_dp
          end if
          call closest_point_segment(q2, p1, q1, u, x, e2)
          if (e2 < dist2) then
            dist2 = e2; s = u; t = 1.0_dp
          end if
        end if
      end if
    end if
    c1 = p1 + s*d1
    c2 = p2 + t*d2
    diff = c1 - c2
    dist2 = dot3(diff, diff)
  end subroutine closest_segment_segment

  pure real(dp) function sqdist(x, y)
    real(dp), intent(in) :: x(3), y(3)
    sqdist = (x(1) - y(1))**2 + (x(2) - y(2))**2 + (x(3) - y(3))**2
  end function sqdist

  pure real(dp) function dot3(x, y)
    real(dp), intent(in) :: x(3), y(3)
    dot3 = x(1)*y(1) + x(2)*y(2) + x(3)*y(3)
  end function dot3

end module closest_primitives
