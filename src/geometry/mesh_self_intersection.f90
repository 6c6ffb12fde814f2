!> Does a closed triangle surface cross itself? Two faces that cross make the surface bound
!> no solid (the divergence-theorem mass properties then count the overlap twice, or with a
!> negative sign: two overlapping cubes weigh 2000 instead of 1875, a vertex pushed through
!> the body gives negative moments), so meshes read from files are refused when any two of
!> their faces intersect other than where they touch.
!>
!> Triangle pair test (after Moller, "A fast triangle-triangle intersection test", JGT 2
!> (1997)), with distances below a tolerance tol [m] counted as zero, so that it needs no
!> knowledge of which nodes two faces share:
!>  - not coplanar: the faces cross when each has vertices strictly on both sides of the
!>    other's plane and the two segments in which they cut the line common to both planes
!>    overlap by more than tol. A face that only reaches the other's plane (a vertex or an
!>    edge within tol of it) touches it: accepted. Faces sharing an edge therefore never
!>    cross unless coplanar; faces sharing one vertex v cut the common line (through v) in
!>    two segments starting at v, which overlap away from v only when they point the same way.
!>  - coplanar (every vertex of one within tol of the other's plane): the faces overlap
!>    when the part of one inside the other (Sutherland-Hodgman clipping) has an area above
!>    tol times their longest edge, i.e. is wider than tol: two neighbours folded onto each
!>    other, or two sheets of surface lying on one another. Flat neighbours (a box face's
!>    two triangles) only share their edge, an overlap of zero area.
!> The pairs to test come from a bounding-box hierarchy over the faces (median splits, as
!> in the SKD-tree, but axis-aligned boxes, which are cheaper to build and to overlap) and
!> its traversal against itself: O(n log n) for a surface whose faces have bounded overlap.
module mesh_self_intersection
  use kinds, only: dp, i8
  use vector_ops, only: cross
  use mesh, only: mesh_t
  use sorting, only: select_kth
  implicit none
  private
  public :: triangles_cross, find_self_intersections, self_intersection_stats_t

  integer, parameter :: leaf_faces = 4   !< most faces in a leaf of the hierarchy

  !> What the search did, for benchmarks and logs.
  type :: self_intersection_stats_t
    integer(i8) :: n_pair_tests = 0      !< triangle pairs given to triangles_cross
    integer :: n_boxes = 0               !< boxes of the hierarchy
  end type self_intersection_stats_t

contains

  !> crossing: the triangles t1 and t2 (vertex coordinates as columns [m]) intersect other
  !> than by touching, to the tolerance tol [m] (see the module comment); point is then a
  !> point of the intersection (the middle of the common segment, or the centroid of the
  !> overlap of coplanar faces), else zero.
  pure subroutine triangles_cross(t1, t2, tol, crossing, point)
    real(dp), intent(in) :: t1(3, 3), t2(3, 3), tol
    logical, intent(out) :: crossing
    real(dp), intent(out) :: point(3)
    call pair_cross(t1, unit_normal(t1), t2, unit_normal(t2), tol, crossing, point)
  end subroutine triangles_cross

  !> triangles_cross with the unit normals n1, n2 of t1, t2 given.
  pure subroutine pair_cross(t1, n1, t2, n2, tol, crossing, point)
    real(dp), intent(in) :: t1(3, 3), n1(3), t2(3, 3), n2(3), tol
    logical, intent(out) :: crossing
    real(dp), intent(out) :: point(3)
    real(dp) :: d1(3), d2(3), line(3), length, p1(3, 2), p2(3, 2), s1(2), s2(2)
    real(dp) :: lo, hi, plo(3), phi(3)
    integer :: k
    crossing = .false.
    point = 0.0_dp
    ! Most pairs the hierarchy offers are neighbours on one side of each other's plane:
    ! decided by the three distances of t2 to t1's plane alone.
    do k = 1, 3
      d2(k) = n1(1)*(t2(1, k) - t1(1, 1)) + n1(2)*(t2(2, k) - t1(2, 1)) + n1(3)*(t2(3, k) - t1(3, 1))
    end do
    where (abs(d2) <= tol) d2 = 0.0_dp
    if (all(d2 == 0.0_dp)) then
      call coplanar_overlap(t1, t2, tol, crossing, point)
      return
    end if
    ! Touching (or apart) unless each strictly straddles the other's plane.
    if (.not. (any(d2 > 0.0_dp) .and. any(d2 < 0.0_dp))) return
    do k = 1, 3
      d1(k) = n2(1)*(t1(1, k) - t2(1, 1)) + n2(2)*(t1(2, k) - t2(2, 1)) + n2(3)*(t1(3, k) - t2(3, 1))
    end do
    where (abs(d1) <= tol) d1 = 0.0_dp
    if (all(d1 == 0.0_dp)) then
      call coplanar_overlap(t1, t2, tol, crossing, point)
      return
    end if
    if (.not. (any(d1 > 0.0_dp) .and. any(d1 < 0.0_dp))) return
    line = cross(n1, n2)
    length = norm2(line)
    if (length <= 0.0_dp) return
    line = line/length
    call plane_cut(t1, d1, p1)
    call plane_cut(t2, d2, p2)
    s1 = matmul(line, p1)
    s2 = matmul(line, p2)
    if (s1(1) > s1(2)) then
      s1 = s1([2, 1]); p1 = p1(:, [2, 1])
    end if
    if (s2(1) > s2(2)) then
      s2 = s2([2, 1]); p2 = p2(:, [2, 1])
    end if
    if (s1(1) >= s2(1)) then
      lo = s1(1); plo = p1(:, 1)
    else
      lo = s2(1); plo = p2(:, 1)
    end if
    if (s1(2) <= s2(2)) then
      hi = s1(2); phi = p1(:, 2)
    else
      hi = s2(2); phi = p2(:, 2)
    end if
    if (hi - lo > tol) then
      crossing = .true.
      point = 0.5_dp*(plo + phi)
    end if
  end subroutine pair_cross

  !> The two ends of the segment in which triangle t, whose vertices lie at signed distances
  !> d from a plane (some > 0, some < 0, the rest exactly 0), cuts that plane.
  pure subroutine plane_cut(t, d, p)
    real(dp), intent(in) :: t(3, 3), d(3)
    real(dp), intent(out) :: p(3, 2)
    integer :: k, j, n
    n = 0
    p = 0.0_dp
    do k = 1, 3
      j = mod(k, 3) + 1
      if (d(k) == 0.0_dp) then
        if (n < 2) n = n + 1
        p(:, n) = t(:, k)
      else if ((d(k) > 0.0_dp .and. d(j) < 0.0_dp) .or. (d(k) < 0.0_dp .and. d(j) > 0.0_dp)) then
        if (n < 2) n = n + 1
        p(:, n) = t(:, k) + (d(k)/(d(k) - d(j)))*(t(:, j) - t(:, k))
      end if
    end do
  end subroutine plane_cut

  !> Coplanar faces: clip t2 by the three edge half-planes of t1 (in t1's plane, its own
  !> normal giving the inside); they overlap when the clipped polygon is wider than tol.
  pure subroutine coplanar_overlap(t1, t2, tol, crossing, point)
    real(dp), intent(in) :: t1(3, 3), t2(3, 3), tol
    logical, intent(out) :: crossing
    real(dp), intent(out) :: point(3)
    real(dp) :: poly(3, 9), next(3, 9), n1(3), a(3), b(3), side(9), area_vector(3), area, longest
    integer :: n, m, k, i, j
    crossing = .false.
    point = 0.0_dp
    n1 = unit_normal(t1)
    poly(:, 1:3) = t2
    n = 3
    do k = 1, 3
      a = t1(:, k)
      b = t1(:, mod(k, 3) + 1)
      do i = 1, n
        side(i) = dot_product(cross(b - a, poly(:, i) - a), n1)
      end do
      m = 0
      do i = 1, n
        j = mod(i, n) + 1
        if (side(i) >= 0.0_dp) then
          m = m + 1
          next(:, m) = poly(:, i)
        end if
        if ((side(i) > 0.0_dp .and. side(j) < 0.0_dp) .or. (side(i) < 0.0_dp .and. side(j) > 0.0_dp)) then
          m = m + 1
          next(:, m) = poly(:, i) + (side(i)/(side(i) - side(j)))*(poly(:, j) - poly(:, i))
        end if
      end do
      n = m
      if (n < 3) return
      poly(:, 1:n) = next(:, 1:n)
    end do
    area_vector = 0.0_dp
    do i = 2, n - 1
      area_vector = area_vector + cross(poly(:, i) - poly(:, 1), poly(:, i + 1) - poly(:, 1))
    end do
    area = 0.5_dp*norm2(area_vector)
    longest = 0.0_dp
    do k = 1, 3
      longest = max(longest, norm2(t1(:, mod(k, 3) + 1) - t1(:, k)), norm2(t2(:, mod(k, 3) + 1) - t2(:, k)))
    end do
    if (area > tol*longest) then
      crossing = .true.
      point = sum(poly(:, 1:n), dim=2)/real(n, dp)
    end if
  end subroutine coplanar_overlap

  pure function unit_normal(t) result(n)
    real(dp), intent(in) :: t(3, 3)
    real(dp) :: n(3), length
    n = cross(t(:, 2) - t(:, 1), t(:, 3) - t(:, 1))
    length = norm2(n)
    if (length > 0.0_dp) then
      n = n/length
    else
      n = 0.0_dp
    end if
  end function unit_normal

  !> Every pair of faces of m (nodes and faces only) that crosses (triangles_cross with
  !> tolerance tol [m]): n_pairs of them; pair = (f, g), f < g, the first in the order
  !> of f then g, and point a point where they cross; pair = 0 when none does.
  subroutine find_self_intersections(m, tol, n_pairs, pair, point, stats)
    type(mesh_t), intent(in) :: m
    real(dp), intent(in) :: tol
    integer(i8), intent(out) :: n_pairs
    integer, intent(out) :: pair(2)
    real(dp), intent(out) :: point(3)
    type(self_intersection_stats_t), intent(out), optional :: stats
    real(dp), allocatable :: lo(:, :), hi(:, :), tri(:, :, :), normal(:, :), centroid(:, :), key(:)
    integer, allocatable :: perm(:), first(:), count(:), right(:), stack(:, :), grown(:, :)
    integer :: nf, n_boxes, top, a, b, f
    integer(i8) :: n_tests

    n_pairs = 0
    pair = 0
    point = 0.0_dp
    n_tests = 0
    nf = m%n_faces
    if (nf < 2) return
    allocate (perm(nf), centroid(3, nf), key(nf))
    do f = 1, nf
      perm(f) = f
      centroid(:, f) = (m%nodes(:, m%faces(1, f)) + m%nodes(:, m%faces(2, f)) + m%nodes(:, m%faces(3, f)))/3.0_dp
    end do
    ! Median splits of boxes of more than leaf_faces >= 3 faces leave at least 2 in each leaf,
    ! so there are at most nf/2 leaves and nf - 1 boxes.
    allocate (lo(3, nf), hi(3, nf), first(nf), count(nf), right(nf))
    n_boxes = 0
    call build(1, nf)
    deallocate (centroid, key)
    ! The faces' coordinates in leaf order: a leaf's triangles are contiguous in memory.
    allocate (tri(3, 3, nf), normal(3, nf))
    do f = 1, nf
      tri(:, 1, f) = m%nodes(:, m%faces(1, perm(f)))
      tri(:, 2, f) = m%nodes(:, m%faces(2, perm(f)))
      tri(:, 3, f) = m%nodes(:, m%faces(3, perm(f)))
      normal(:, f) = unit_normal(tri(:, :, f))
    end do

    ! Self-traversal: (a, a) stands for the pairs within box a, (a, b) for those across.
    allocate (stack(2, 256))
    top = 1
    stack(:, 1) = [1, 1]
    do while (top > 0)
      a = stack(1, top)
      b = stack(2, top)
      top = top - 1
      if (a == b) then
        if (right(a) == 0) then
          call test_leaves(a, a)
        else
          call push(a + 1, a + 1)
          call push(right(a), right(a))
          call push(a + 1, right(a))
        end if
      else if (all(lo(:, a) <= hi(:, b)) .and. all(lo(:, b) <= hi(:, a))) then
        if (right(a) == 0 .and. right(b) == 0) then
          call test_leaves(a, b)
        else if (right(b) == 0 .or. (right(a) /= 0 .and. count(a) >= count(b))) then
          call push(a + 1, b)
          call push(right(a), b)
        else
          call push(a, b + 1)
          call push(a, right(b))
        end if
      end if
    end do
    if (present(stats)) then
      stats%n_pair_tests = n_tests
      stats%n_boxes = n_boxes
    end if

  contains

    recursive subroutine build(i1, i2)
      integer, intent(in) :: i1, i2
      integer :: k, i, j, axis, mid
      real(dp) :: clo(3), chi(3)
      n_boxes = n_boxes + 1
      k = n_boxes
      first(k) = i1
      count(k) = i2 - i1 + 1
      right(k) = 0
      if (i2 - i1 + 1 <= leaf_faces) then
        lo(:, k) = huge(1.0_dp)
        hi(:, k) = -huge(1.0_dp)
        do i = i1, i2
          do j = 1, 3
            lo(:, k) = min(lo(:, k), m%nodes(:, m%faces(j, perm(i))))
            hi(:, k) = max(hi(:, k), m%nodes(:, m%faces(j, perm(i))))
          end do
        end do
        return
      end if
      ! Split along the longest extent of the centroids, at their median.
      clo = huge(1.0_dp)
      chi = -huge(1.0_dp)
      do i = i1, i2
        clo = min(clo, centroid(:, perm(i)))
        chi = max(chi, centroid(:, perm(i)))
      end do
      axis = maxloc(chi - clo, dim=1)
      do i = i1, i2
        key(perm(i)) = centroid(axis, perm(i))
      end do
      mid = i1 + (i2 - i1 + 1)/2 - 1
      call select_kth(perm, key, i1, i2, mid)
      call build(i1, mid)
      right(k) = n_boxes + 1
      call build(mid + 1, i2)
      ! Bounds bottom-up, the union of the children's: each vertex is visited once, not
      ! once per level.
      lo(:, k) = min(lo(:, k + 1), lo(:, right(k)))
      hi(:, k) = max(hi(:, k + 1), hi(:, right(k)))
    end subroutine build

    subroutine push(x, y)
      integer, intent(in) :: x, y
      if (top == size(stack, 2)) then
        allocate (grown(2, 2*size(stack, 2)))
        grown(:, 1:top) = stack(:, 1:top)
        call move_alloc(grown, stack)
      end if
      top = top + 1
      stack(:, top) = [x, y]
    end subroutine push

    subroutine test_leaves(x, y)
      integer, intent(in) :: x, y
      integer :: i, j, j1, fi, fj
      real(dp) :: p(3)
      logical :: crossing
      do i = first(x), first(x) + count(x) - 1
        j1 = first(y)
        if (x == y) j1 = i + 1
        do j = j1, first(y) + count(y) - 1
          n_tests = n_tests + 1
          call pair_cross(tri(:, :, i), normal(:, i), tri(:, :, j), normal(:, j), tol, crossing, p)
          if (.not. crossing) cycle
          n_pairs = n_pairs + 1
          fi = min(perm(i), perm(j))
          fj = max(perm(i), perm(j))
          if (pair(1) == 0 .or. fi < pair(1) .or. (fi == pair(1) .and. fj < pair(2))) then
            pair = [fi, fj]
            point = p
          end if
        end do
      end do
    end subroutine test_leaves

  end subroutine find_self_intersections

end module mesh_self_intersection
