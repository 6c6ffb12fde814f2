!> The whole set of contact features between two posed mesh bodies within a tolerance, and
!> the overlap test for two posed bodies.
!>
!> Contact features: every vertex-face pair (both ways) and every edge-edge pair closer
!> than the tolerance, each with its two points and a unit normal from A towards B. One
!> closest point is not enough for the response (a box resting face down needs its four
!> corners), so the traversal keeps every pair under the tolerance instead of the best one.
!> Duplicates are removed so that each physical contact point appears once:
!>  - edge-edge pairs count only where both closest points are interior to both edges and
!>    both edges are creases (a flat edge, such as the diagonal of a box face, lies inside a
!>    plane whose contacts the vertex-face pairs already give; an edge-edge pair closest at
!>    an endpoint is a vertex-edge contact, given by the vertex against the edge's faces);
!>  - features whose two points coincide with those of another (a vertex near an edge shared
!>    by two faces; a vertex touching a vertex, found from both sides) are kept once.
!>
!> Overlap: the surfaces intersect (some edge of one crosses a triangle of the other,
!> touching included) or one body lies inside the other (generalised winding number of one
!> vertex). Touching bodies count as overlapping: ricochet keeps a minimum separation, so a
!> deck that starts with bodies in contact is as wrong as one that starts interpenetrating.
module contact_features
  use kinds, only: dp, i8
  use vector_ops, only: cross
  use quaternion, only: quat_to_matrix
  use error_status, only: error_t, ERR_INPUT
  use skd_tree, only: skd_tree_t, LEAF_SIZE, owns_vertex, owns_edge, sharp_edge
  use closest_primitives, only: closest_point_triangle, closest_segment_segment, REGION_FACE, REGION_VERTEX_A, &
                                REGION_VERTEX_B, REGION_VERTEX_C, REGION_EDGE_AB, REGION_EDGE_BC, REGION_EDGE_CA
  use mesh_distance, only: query_stats_t, relative_pose_t, make_relative_pose, box_gap2, point_box_gap2, STACK_SIZE, &
                           edge_nodes, FEATURE_VERTEX_FACE, FEATURE_FACE_VERTEX, FEATURE_EDGE_EDGE
  implicit none
  private
  public :: contact_feature_t, find_contact_features, bodies_overlap, check_no_overlap, winding_number

  !> Edge parameters this close to 0 or 1 make an edge-edge pair a vertex contact.
  real(dp), parameter :: endpoint_fraction = 1.0e-9_dp

  type :: contact_feature_t
    integer :: kind = 0                  !< FEATURE_VERTEX_FACE, FEATURE_FACE_VERTEX, FEATURE_EDGE_EDGE
    integer :: feature_a(2) = 0          !< as in distance_result_t: vertex (node, 0), face (face, 0), edge (n1, n2)
    integer :: feature_b(2) = 0
    real(dp) :: distance = 0.0_dp        !< [m]
    real(dp) :: point_a(3) = 0.0_dp      !< world [m]
    real(dp) :: point_b(3) = 0.0_dp      !< world [m]
    real(dp) :: normal(3) = 0.0_dp       !< unit, world, from A towards B
  end type contact_feature_t

contains

  !> All contact features of bodies A and B closer than tolerance [m]. features is grown as
  !> needed (kept between calls to avoid reallocation); features(1:n_features) are valid.
  subroutine find_contact_features(tree_a, xa, qa, tree_b, xb, qb, tolerance, features, n_features, stats)
    type(skd_tree_t), intent(in) :: tree_a, tree_b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4), tolerance
    type(contact_feature_t), allocatable, intent(inout) :: features(:)
    integer, intent(out) :: n_features
    type(query_stats_t), intent(inout), optional :: stats
    type(relative_pose_t) :: rel
    integer :: stack_a(STACK_SIZE), stack_b(STACK_SIZE), top, na, nb, i, j, kept
    real(dp) :: tol2, ra(3, 3), tb(3, 3, LEAF_SIZE), nb_a(3, LEAF_SIZE), same2
    integer(i8) :: n_box, n_leaf, n_prim
    logical :: duplicate

    if (.not. allocated(features)) allocate (features(16))
    n_features = 0
    rel = make_relative_pose(tree_a%radius, xa, qa, tree_b%radius, xb, qb)
    ra = quat_to_matrix(qa)
    tol2 = tolerance**2
    n_box = 1; n_leaf = 0; n_prim = 0
    top = 0
    if (box_gap2(tree_a%box(:, 1), tree_b%box(:, 1), rel, tol2) <= tol2) call push(1, 1)
    do while (top > 0)
      na = stack_a(top)
      nb = stack_b(top)
      top = top - 1
      if (tree_a%right(na) == 0 .and. tree_b%right(nb) == 0) then
        n_leaf = n_leaf + 1
        call leaf_pair(na, nb)
      else if (tree_b%right(nb) == 0 .or. (tree_a%right(na) /= 0 .and. &
                                          sum(tree_a%box(4:6, na)) >= sum(tree_b%box(4:6, nb)))) then
        n_box = n_box + 2
        if (box_gap2(tree_a%box(:, na + 1), tree_b%box(:, nb), rel, tol2) <= tol2) call push(na + 1, nb)
        if (box_gap2(tree_a%box(:, tree_a%right(na)), tree_b%box(:, nb), rel, tol2) <= tol2) call push(tree_a%right(na), nb)
      else
        n_box = n_box + 2
        if (box_gap2(tree_a%box(:, na), tree_b%box(:, nb + 1), rel, tol2) <= tol2) call push(na, nb + 1)
        if (box_gap2(tree_a%box(:, na), tree_b%box(:, tree_b%right(nb)), rel, tol2) <= tol2) call push(na, tree_b%right(nb))
      end if
    end do

    ! Keep one feature per distinct pair of points (the first found, then the closest).
    same2 = (1.0e-10_dp*(tree_a%radius + tree_b%radius))**2
    kept = 0
    do i = 1, n_features
      duplicate = .false.
      do j = 1, kept
        if (sum((features(i)%point_a - features(j)%point_a)**2) <= same2 .and. &
            sum((features(i)%point_b - features(j)%point_b)**2) <= same2) then
          duplicate = .true.
          if (features(i)%distance < features(j)%distance) features(j) = features(i)
          exit
        end if
      end do
      if (.not. duplicate) then
        kept = kept + 1
        if (kept /= i) features(kept) = features(i)
      end if
    end do
    n_features = kept
    if (present(stats)) then
      stats%box_pairs = stats%box_pairs + n_box
      stats%leaf_pairs = stats%leaf_pairs + n_leaf
      stats%primitive_tests = stats%primitive_tests + n_prim
    end if

  contains

    subroutine push(ia, ib)
      integer, intent(in) :: ia, ib
      top = top + 1
      stack_a(top) = ia
      stack_b(top) = ib
    end subroutine push

    subroutine leaf_pair(na, nb)
      integer, intent(in) :: na, nb
      integer :: sa, sb, ka, kb, jb, fa0, fa1, fb0, fb1, region
      real(dp) :: q(3), d2, s, t, c1(3), c2(3), n(3), length
      logical :: keep
      fa0 = tree_a%first(na)
      fa1 = fa0 + tree_a%count(na) - 1
      fb0 = tree_b%first(nb)
      fb1 = fb0 + tree_b%count(nb) - 1
      do sb = fb0, fb1
        jb = sb - fb0 + 1
        do kb = 1, 3
          tb(:, kb, jb) = matmul(rel%r, tree_b%tri(:, kb, sb)) + rel%t
        end do
        nb_a(:, jb) = matmul(rel%r, tree_b%normal(:, sb))
      end do
      do sa = fa0, fa1
        do ka = 1, 3
          if (owns_vertex(tree_a%flags(sa), ka)) then
            do sb = fb0, fb1
              jb = sb - fb0 + 1
              call closest_point_triangle(tree_a%tri(:, ka, sa), tb(:, 1, jb), tb(:, 2, jb), tb(:, 3, jb), q, region, d2)
              n_prim = n_prim + 1
              if (d2 > tol2) cycle
              n = -nb_a(:, jb)
              if (region /= REGION_FACE .and. d2 > 0.0_dp) then
                call boundary_feature((q - tree_a%tri(:, ka, sa))/sqrt(d2), n, tree_b%flags(sb), region, keep)
                if (.not. keep) cycle
              end if
              call add(FEATURE_VERTEX_FACE, [tree_a%tri_nodes(ka, sa), 0], [tree_b%face_id(sb), 0], d2, &
                       tree_a%tri(:, ka, sa), q, n)
            end do
          end if
          if (owns_edge(tree_a%flags(sa), ka) .and. sharp_edge(tree_a%flags(sa), ka)) then
            do sb = fb0, fb1
              jb = sb - fb0 + 1
              do kb = 1, 3
                if (.not. (owns_edge(tree_b%flags(sb), kb) .and. sharp_edge(tree_b%flags(sb), kb))) cycle
                call closest_segment_segment(tree_a%tri(:, ka, sa), tree_a%tri(:, mod(ka, 3) + 1, sa), &
                                             tb(:, kb, jb), tb(:, mod(kb, 3) + 1, jb), s, t, c1, c2, d2)
                n_prim = n_prim + 1
                if (d2 > tol2) cycle
                if (min(s, 1.0_dp - s, t, 1.0_dp - t) <= endpoint_fraction) cycle
                n = cross(tree_a%tri(:, mod(ka, 3) + 1, sa) - tree_a%tri(:, ka, sa), &
                          tb(:, mod(kb, 3) + 1, jb) - tb(:, kb, jb))
                length = norm2(n)
                if (length > 0.0_dp) then
                  n = n/length
                else
                  n = tree_a%normal(:, sa)
                end if
                ! The edge-edge normal is the common perpendicular, pointing from A to B: the
                ! sign follows the gap when there is one, else A's outward face normal.
                if (d2 > 0.0_dp) then
                  if (dot_product(n, c2 - c1) < 0.0_dp) n = -n
                else if (dot_product(n, tree_a%normal(:, sa)) < 0.0_dp) then
                  n = -n
                end if
                call add(FEATURE_EDGE_EDGE, edge_nodes(tree_a, sa, ka), edge_nodes(tree_b, sb, kb), d2, c1, c2, n)
              end do
            end do
          end if
        end do
      end do
      do sb = fb0, fb1
        jb = sb - fb0 + 1
        do kb = 1, 3
          if (.not. owns_vertex(tree_b%flags(sb), kb)) cycle
          do sa = fa0, fa1
            call closest_point_triangle(tb(:, kb, jb), tree_a%tri(:, 1, sa), tree_a%tri(:, 2, sa), tree_a%tri(:, 3, sa), &
                                        q, region, d2)
            n_prim = n_prim + 1
            if (d2 > tol2) cycle
            n = tree_a%normal(:, sa)
            if (region /= REGION_FACE .and. d2 > 0.0_dp) then
              call boundary_feature((tb(:, kb, jb) - q)/sqrt(d2), n, tree_a%flags(sa), region, keep)
              if (.not. keep) cycle
            end if
            call add(FEATURE_FACE_VERTEX, [tree_a%face_id(sa), 0], [tree_b%tri_nodes(kb, sb), 0], d2, q, tb(:, kb, jb), n)
          end do
        end do
      end do
    end subroutine leaf_pair

    !> A vertex whose closest point lies on a triangle's edge or corner. Its normal (n, in:
    !> the face normal; out) is the direction between the points, unless that is the face
    !> normal up to round-off (a corner straight above the diagonal of a box face: at a gap of
    !> 1e-6 m the difference of the points tilted it by 1e-10 rad, and a box landing flat
    !> drifted sideways at 1e-10 m/s). Where that boundary is flat (an edge between coplanar
    !> faces, or a corner all of whose edges in this triangle are), the vertex lies over the
    !> neighbouring face, which gives the true feature; this one, tilted across the flat edge,
    !> is dropped (keep false) unless the vertex is straight above the boundary. Speculative
    !> contacts search far enough for it to matter: a block sliding on an incline had such a
    !> feature 1.5 mm away with a normal 70 degrees off the face's, which pushed it sideways.
    pure subroutine boundary_feature(direction, n, flags, region, keep)
      real(dp), intent(in) :: direction(3)
      real(dp), intent(inout) :: n(3)
      integer, intent(in) :: flags, region
      logical, intent(out) :: keep
      logical :: flat
      keep = .true.
      select case (region)
      case (REGION_EDGE_AB)
        flat = .not. sharp_edge(flags, 1)
      case (REGION_EDGE_BC)
        flat = .not. sharp_edge(flags, 2)
      case (REGION_EDGE_CA)
        flat = .not. sharp_edge(flags, 3)
      case (REGION_VERTEX_A)
        flat = .not. (sharp_edge(flags, 1) .or. sharp_edge(flags, 3))
      case (REGION_VERTEX_B)
        flat = .not. (sharp_edge(flags, 1) .or. sharp_edge(flags, 2))
      case (REGION_VERTEX_C)
        flat = .not. (sharp_edge(flags, 2) .or. sharp_edge(flags, 3))
      case default
        flat = .false.
      end select
      if (dot_product(direction, n) >= 1.0_dp - 1.0e-12_dp) return   ! straight above: the face normal
      if (flat .and. dot_product(direction, n) < 1.0_dp - 1.0e-9_dp) then
        keep = .false.
        return
      end if
      if (.not. flat) n = direction
    end subroutine boundary_feature

    !> Appends a feature; points and normal given in A's frame.
    subroutine add(kind, fa, fb, d2, pa, pb, n)
      integer, intent(in) :: kind, fa(2), fb(2)
      real(dp), intent(in) :: d2, pa(3), pb(3), n(3)
      type(contact_feature_t), allocatable :: grown(:)
      if (n_features == size(features)) then
        allocate (grown(2*size(features)))
        grown(1:n_features) = features(1:n_features)
        call move_alloc(grown, features)
      end if
      n_features = n_features + 1
      features(n_features)%kind = kind
      features(n_features)%feature_a = fa
      features(n_features)%feature_b = fb
      features(n_features)%distance = sqrt(d2)
      features(n_features)%point_a = xa + matmul(ra, pa)
      features(n_features)%point_b = xa + matmul(ra, pb)
      features(n_features)%normal = matmul(ra, n)
    end subroutine add

  end subroutine find_contact_features

  !> True when bodies A and B at their poses intersect, touch, or one contains the other.
  logical function bodies_overlap(tree_a, xa, qa, tree_b, xb, qb, stats) result(overlap)
    type(skd_tree_t), intent(in) :: tree_a, tree_b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4)
    type(query_stats_t), intent(inout), optional :: stats
    type(relative_pose_t) :: rel
    integer :: stack_a(STACK_SIZE), stack_b(STACK_SIZE), top, na, nb, sa, sb, k, jb
    real(dp) :: tb(3, 3, LEAF_SIZE), p(3), ra(3, 3), rb(3, 3)
    integer(i8) :: n_box, n_leaf, n_prim

    overlap = .false.
    rel = make_relative_pose(tree_a%radius, xa, qa, tree_b%radius, xb, qb)
    n_box = 1; n_leaf = 0; n_prim = 0
    top = 0
    if (box_gap2(tree_a%box(:, 1), tree_b%box(:, 1), rel, 0.0_dp) <= 0.0_dp) call push(1, 1)
    do while (top > 0 .and. .not. overlap)
      na = stack_a(top)
      nb = stack_b(top)
      top = top - 1
      if (tree_a%right(na) == 0 .and. tree_b%right(nb) == 0) then
        n_leaf = n_leaf + 1
        do sb = tree_b%first(nb), tree_b%first(nb) + tree_b%count(nb) - 1
          jb = sb - tree_b%first(nb) + 1
          do k = 1, 3
            tb(:, k, jb) = matmul(rel%r, tree_b%tri(:, k, sb)) + rel%t
          end do
        end do
        do sa = tree_a%first(na), tree_a%first(na) + tree_a%count(na) - 1
          do jb = 1, tree_b%count(nb)
            n_prim = n_prim + 1
            if (triangles_intersect(tree_a%tri(:, :, sa), tb(:, :, jb))) then
              overlap = .true.
              exit
            end if
          end do
          if (overlap) exit
        end do
      else if (tree_b%right(nb) == 0 .or. (tree_a%right(na) /= 0 .and. &
                                          sum(tree_a%box(4:6, na)) >= sum(tree_b%box(4:6, nb)))) then
        n_box = n_box + 2
        if (box_gap2(tree_a%box(:, na + 1), tree_b%box(:, nb), rel, 0.0_dp) <= 0.0_dp) call push(na + 1, nb)
        if (box_gap2(tree_a%box(:, tree_a%right(na)), tree_b%box(:, nb), rel, 0.0_dp) <= 0.0_dp) call push(tree_a%right(na), nb)
      else
        n_box = n_box + 2
        if (box_gap2(tree_a%box(:, na), tree_b%box(:, nb + 1), rel, 0.0_dp) <= 0.0_dp) call push(na, nb + 1)
        if (box_gap2(tree_a%box(:, na), tree_b%box(:, tree_b%right(nb)), rel, 0.0_dp) <= 0.0_dp) call push(na, tree_b%right(nb))
      end if
    end do
    if (.not. overlap) then
      ! Surfaces apart: either disjoint or nested. One vertex of each decides.
      ra = quat_to_matrix(qa)
      rb = quat_to_matrix(qb)
      p = matmul(transpose(rb), xa + matmul(ra, tree_a%tri(:, 1, 1)) - xb)
      overlap = abs(winding_number(tree_b, p)) > 0.5_dp
      if (.not. overlap) then
        p = matmul(transpose(ra), xb + matmul(rb, tree_b%tri(:, 1, 1)) - xa)
        overlap = abs(winding_number(tree_a, p)) > 0.5_dp
      end if
      n_prim = n_prim + tree_a%n_faces + tree_b%n_faces
    end if
    if (present(stats)) then
      stats%box_pairs = stats%box_pairs + n_box
      stats%leaf_pairs = stats%leaf_pairs + n_leaf
      stats%primitive_tests = stats%primitive_tests + n_prim
    end if
  contains
    subroutine push(ia, ib)
      integer, intent(in) :: ia, ib
      top = top + 1
      stack_a(top) = ia
      stack_b(top) = ib
    end subroutine push
  end function bodies_overlap

  !> Deck check: an ERR_INPUT naming both bodies when they overlap at their initial poses.
  subroutine check_no_overlap(tree_a, xa, qa, name_a, tree_b, xb, qb, name_b, err)
    type(skd_tree_t), intent(in) :: tree_a, tree_b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4)
    character(len=*), intent(in) :: name_a, name_b
    type(error_t), intent(inout) :: err
    if (bodies_overlap(tree_a, xa, qa, tree_b, xb, qb)) &
      call err%set(ERR_INPUT, 'bodies '//name_a//' and '//name_b// &
                   ' overlap (intersect, touch or contain one another) at their initial poses')
  end subroutine check_no_overlap

  !> Generalised winding number of the closed surface about point p (body frame): 1 inside,
  !> 0 outside, for p off the surface. Sum of the signed solid angles of the faces
  !> (van Oosterom and Strackee), free of the degenerate cases of ray casting. 0 at once
  !> for p outside the tree's root box, which holds every face (a sphere beside a wall:
  !> most pairs of a gas in a box; the atan2 per face was a third of the start-up overlap
  !> check), with a relative margin for the rounding of the box's axes.
  pure real(dp) function winding_number(tree, p)
    type(skd_tree_t), intent(in) :: tree
    real(dp), intent(in) :: p(3)
    real(dp) :: a(3), b(3), c(3), la, lb, lc, det, den, total, pi
    integer :: s
    winding_number = 0.0_dp
    if (tree%n_boxes > 0) then
      if (point_box_gap2(p, tree%box(:, 1)) > (1.0e-9_dp*tree%radius)**2) return
    end if
    pi = 4.0_dp*atan(1.0_dp)
    total = 0.0_dp
    do s = 1, tree%n_faces
      a = tree%tri(:, 1, s) - p
      b = tree%tri(:, 2, s) - p
      c = tree%tri(:, 3, s) - p
      la = norm2(a); lb = norm2(b); lc = norm2(c)
      det = dot_product(a, cross(b, c))
      den = la*lb*lc + dot_product(a, b)*lc + dot_product(b, c)*la + dot_product(c, a)*lb
      total = total + 2.0_dp*atan2(det, den)
    end do
    winding_number = total/(4.0_dp*pi)
  end function winding_number

  !> Two triangles (columns are vertices) share a point. Non-coplanar triangles meet iff an
  !> edge of one meets the other; coplanar ones are handled in the plane.
  pure logical function triangles_intersect(t1, t2)
    real(dp), intent(in) :: t1(3, 3), t2(3, 3)
    integer :: k
    triangles_intersect = .true.
    do k = 1, 3
      if (segment_meets_triangle(t1(:, k), t1(:, mod(k, 3) + 1), t2)) return
      if (segment_meets_triangle(t2(:, k), t2(:, mod(k, 3) + 1), t1)) return
    end do
    triangles_intersect = .false.
  end function triangles_intersect

  pure real(dp) function orient3(a, b, c, d)
    real(dp), intent(in) :: a(3), b(3), c(3), d(3)
    orient3 = dot_product(d - a, cross(b - a, c - a))
  end function orient3

  pure real(dp) function orient2(a, b, c)
    real(dp), intent(in) :: a(2), b(2), c(2)
    orient2 = (b(1) - a(1))*(c(2) - a(2)) - (b(2) - a(2))*(c(1) - a(1))
  end function orient2

  !> Segment pq shares a point with triangle t (touching included).
  pure logical function segment_meets_triangle(p, q, t) result(meets)
    real(dp), intent(in) :: p(3), q(3), t(3, 3)
    real(dp) :: dp_, dq, s1, s2, s3, n(3)
    real(dp) :: p2(2), q2(2), a2(2), b2(2), c2(2)
    integer :: drop, i1, i2
    meets = .false.
    dp_ = orient3(t(:, 1), t(:, 2), t(:, 3), p)
    dq = orient3(t(:, 1), t(:, 2), t(:, 3), q)
    if ((dp_ > 0.0_dp .and. dq > 0.0_dp) .or. (dp_ < 0.0_dp .and. dq < 0.0_dp)) return
    if (dp_ /= 0.0_dp .or. dq /= 0.0_dp) then
      s1 = orient3(p, q, t(:, 1), t(:, 2))
      s2 = orient3(p, q, t(:, 2), t(:, 3))
      s3 = orient3(p, q, t(:, 3), t(:, 1))
      meets = (s1 >= 0.0_dp .and. s2 >= 0.0_dp .and. s3 >= 0.0_dp) .or. &
              (s1 <= 0.0_dp .and. s2 <= 0.0_dp .and. s3 <= 0.0_dp)
      return
    end if
    ! Coplanar: drop the dominant axis of the normal and work in the plane.
    n = cross(t(:, 2) - t(:, 1), t(:, 3) - t(:, 1))
    if (all(n == 0.0_dp)) return
    drop = maxloc(abs(n), dim=1)
    i1 = mod(drop, 3) + 1
    i2 = mod(drop + 1, 3) + 1
    p2 = [p(i1), p(i2)]; q2 = [q(i1), q(i2)]
    a2 = [t(i1, 1), t(i2, 1)]; b2 = [t(i1, 2), t(i2, 2)]; c2 = [t(i1, 3), t(i2, 3)]
    meets = point_in_triangle2(p2, a2, b2, c2) .or. point_in_triangle2(q2, a2, b2, c2) .or. &
            segments_meet2(p2, q2, a2, b2) .or. segments_meet2(p2, q2, b2, c2) .or. segments_meet2(p2, q2, c2, a2)
  end function segment_meets_triangle

  pure logical function point_in_triangle2(p, a, b, c)
    real(dp), intent(in) :: p(2), a(2), b(2), c(2)
    real(dp) :: s1, s2, s3
    s1 = orient2(a, b, p)
    s2 = orient2(b, c, p)
    s3 = orient2(c, a, p)
    point_in_triangle2 = (s1 >= 0.0_dp .and. s2 >= 0.0_dp .and. s3 >= 0.0_dp) .or. &
                         (s1 <= 0.0_dp .and. s2 <= 0.0_dp .and. s3 <= 0.0_dp)
  end function point_in_triangle2

  pure logical function segments_meet2(p, q, a, b)
    real(dp), intent(in) :: p(2), q(2), a(2), b(2)
    real(dp) :: o1, o2, o3, o4
    o1 = orient2(p, q, a)
    o2 = orient2(p, q, b)
    o3 = orient2(a, b, p)
    o4 = orient2(a, b, q)
    if (((o1 > 0.0_dp .and. o2 < 0.0_dp) .or. (o1 < 0.0_dp .and. o2 > 0.0_dp)) .and. &
        ((o3 > 0.0_dp .and. o4 < 0.0_dp) .or. (o3 < 0.0_dp .and. o4 > 0.0_dp))) then
      segments_meet2 = .true.
      return
    end if
    ! collinear touching cases
    segments_meet2 = (o1 == 0.0_dp .and. on_segment2(p, q, a)) .or. (o2 == 0.0_dp .and. on_segment2(p, q, b)) .or. &
                     (o3 == 0.0_dp .and. on_segment2(a, b, p)) .or. (o4 == 0.0_dp .and. on_segment2(a, b, q))
  end function segments_meet2

  pure logical function on_segment2(a, b, p)
    real(dp), intent(in) :: a(2), b(2), p(2)
    on_segment2 = p(1) >= min(a(1), b(1)) .and. p(1) <= max(a(1), b(1)) .and. &
                  p(2) >= min(a(2), b(2)) .and. p(2) <= max(a(2), b(2))
  end function on_segment2

end module contact_features
