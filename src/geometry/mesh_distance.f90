!> Exact distance and closest points between two posed bodies: triangle meshes (through
!> their SKD-trees) and analytic spheres. For meshes the distance is the minimum over
!> vertex-face pairs of A to B, of B to A, and edge-edge pairs; for surfaces that do not
!> cross this is the exact distance between the two surfaces. (For crossing surfaces it is
!> not 0 in general: use contact_features' bodies_overlap to detect that case.)
!>
!> Everything is computed in A's body frame: B's points are mapped by the relative pose
!> p -> R_rel p + t_rel (R_rel = R_A^T R_B, t_rel = R_A^T (x_B - x_A)), so A's data is used
!> as stored and only the B leaves actually reached are transformed. Results are returned
!> in the world frame. Poses: world = x + R(q) p.
!>
!> Pruning bound between oriented box a (A frame) and oriented box b (B frame): seen in a's
!> own frame, box b lies inside the axis-aligned box with b's centre and half extents
!> |M| h_b, where M holds b's axes in a's frame (|.| taken entry-wise); the gap between box
!> a and that enclosing box is a lower bound on the distance between anything in box a and
!> anything in box b. The same holds with the roles swapped (a enclosed in b's frame); the
!> larger of the two bounds is used. A pair is skipped when its bound is not below the best
!> distance so far.
module mesh_distance
  use kinds, only: dp, i8
  use vector_ops, only: cross
  use quaternion, only: quat_to_matrix
  use mesh, only: mesh_t
  use skd_tree, only: skd_tree_t, LEAF_SIZE, owns_vertex, owns_edge
  use closest_primitives, only: closest_point_triangle, closest_segment_segment
  implicit none
  private
  public :: distance_result_t, query_stats_t, relative_pose_t, feature_pair_t
  public :: mesh_mesh_distance, mesh_mesh_distance_brute, sphere_sphere_distance, sphere_mesh_distance
  public :: make_relative_pose, box_gap2, point_box_gap2, edge_nodes
  public :: FEATURE_NONE, FEATURE_VERTEX_FACE, FEATURE_FACE_VERTEX, FEATURE_EDGE_EDGE, &
            FEATURE_SPHERE_SPHERE, FEATURE_SPHERE_FACE
  public :: STACK_SIZE

  !> Which features realise the distance. Vertex: (node, 0); face: (face, 0);
  !> edge: (node1, node2) with node1 < node2; sphere: (0, 0). Indices are the mesh's.
  integer, parameter :: FEATURE_NONE = 0
  integer, parameter :: FEATURE_VERTEX_FACE = 1     !< vertex of A, face of B
  integer, parameter :: FEATURE_FACE_VERTEX = 2     !< face of A, vertex of B
  integer, parameter :: FEATURE_EDGE_EDGE = 3
  integer, parameter :: FEATURE_SPHERE_SPHERE = 4
  integer, parameter :: FEATURE_SPHERE_FACE = 5     !< sphere A, face of mesh B

  !> Pending box pairs of a depth-first traversal never exceed depth_A + depth_B + 1; the
  !> trees are balanced (median splits), so 2 * 64 covers any mesh that fits in memory.
  integer, parameter :: STACK_SIZE = 128

  !> A query keeps B's boxes and faces in A's frame, each transformed once, for trees up to
  !> these sizes (boxes, faces; about 3 KB of stack): the small meshes of a gas or a pile (a
  !> box has 15 boxes and 12 faces). Larger trees transform a box or a leaf at every visit.
  integer, parameter :: CACHE_BOXES = 31, CACHE_SLOTS = 16

  type :: distance_result_t
    logical :: found = .false.            !< false: nothing closer than the upper bound
    real(dp) :: distance = huge(1.0_dp)   !< [m]; the upper bound when not found
    real(dp) :: point_a(3) = 0.0_dp       !< closest point on A, world [m]
    real(dp) :: point_b(3) = 0.0_dp       !< closest point on B, world [m]
    real(dp) :: normal(3) = 0.0_dp        !< unit, world, from A towards B
    integer :: kind = FEATURE_NONE
    integer :: feature_a(2) = 0
    integer :: feature_b(2) = 0
  end type distance_result_t

  !> The primitive pair (slots and corners of the two trees, FEATURE_* kind) that realised a
  !> query's distance: a query of the same two trees at nearby poses (the next iterate of
  !> conservative advancement) tests it first, so that its traversal starts with a bound
  !> close to the answer and prunes most box pairs.
  type :: feature_pair_t
    integer :: kind = FEATURE_NONE
    integer :: sa = 0, ka = 0, sb = 0, kb = 0
  end type feature_pair_t

  !> Work counters; queries add to them (reset with stats = query_stats_t()).
  type :: query_stats_t
    integer(i8) :: box_pairs = 0          !< box pairs (or point-box tests) whose bound was computed
    integer(i8) :: leaf_pairs = 0         !< leaf pairs whose primitives were tested
    integer(i8) :: primitive_tests = 0    !< point-triangle and segment-segment tests
  end type query_stats_t

  !> B's frame seen from A's: p_A = r p_B + t; abs_r = |r| entry-wise.
  type :: relative_pose_t
    real(dp) :: r(3, 3), abs_r(3, 3), t(3)
    real(dp) :: slack        !< added to every box half extent: covers rounding [m]
  end type relative_pose_t

contains

  pure function make_relative_pose(tree_a_radius, xa, qa, tree_b_radius, xb, qb) result(rel)
    real(dp), intent(in) :: tree_a_radius, xa(3), qa(4), tree_b_radius, xb(3), qb(4)
    type(relative_pose_t) :: rel
    real(dp) :: ra(3, 3), rb(3, 3)
    ra = quat_to_matrix(qa)
    rb = quat_to_matrix(qb)
    rel%r = matmul(transpose(ra), rb)
    rel%abs_r = abs(rel%r)
    rel%t = matmul(transpose(ra), xb - xa)
    ! Rounding in the transformed box centres is a few ulps of the coordinates involved.
    rel%slack = 1.0e-13_dp*(tree_a_radius + tree_b_radius + norm2(rel%t))
  end function make_relative_pose

  !> Lower bound on the squared distance between oriented box a (A frame) and oriented box
  !> b (B frame), the largest of three (see the module header): along the line of centres,
  !> then b enclosed in a's frame, then a enclosed in b's frame. As soon as one exceeds
  !> cutoff it is returned (the pair is pruned whatever the others say), which saves the
  !> rest of the work for most pruned pairs.
  pure real(dp) function box_gap2(a, b, rel, cutoff)
    real(dp), intent(in) :: a(15), b(15)
    type(relative_pose_t), intent(in) :: rel
    real(dp), intent(in) :: cutoff
    real(dp) :: cb(3), vb(3, 3)
    call transform_box(b, rel, cb, vb)
    box_gap2 = box_gap2_posed(a, b, cb, vb, rel%slack, cutoff)
  end function box_gap2

  !> Box b's centre cb and axes vb (columns) in A's body frame. A query reaches each box of
  !> B with several boxes of A: it transforms each once (the same arithmetic as before, so
  !> the bounds are bitwise those of box_gap2).
  pure subroutine transform_box(b, rel, cb, vb)
    real(dp), intent(in) :: b(15)
    type(relative_pose_t), intent(in) :: rel
    real(dp), intent(out) :: cb(3), vb(3, 3)
    integer :: i, j
    do i = 1, 3
      cb(i) = rel%r(i, 1)*b(1) + rel%r(i, 2)*b(2) + rel%r(i, 3)*b(3) + rel%t(i)
    end do
    do j = 1, 3
      do i = 1, 3
        vb(i, j) = rel%r(i, 1)*b(3 + 3*j + 1) + rel%r(i, 2)*b(3 + 3*j + 2) + rel%r(i, 3)*b(3 + 3*j + 3)
      end do
    end do
  end subroutine transform_box

  !> box_gap2 with b's centre and axes already in A's frame (transform_box); b(4:6) are
  !> still read for its half extents.
  pure real(dp) function box_gap2_posed(a, b, cb, v, slack, cutoff)
    real(dp), intent(in) :: a(15), b(15), cb(3), v(3, 3), slack, cutoff
    real(dp) :: c(3), d(3), e(3), m(3, 3), am(3, 3), g(3), s1, s2, s3, len
    integer :: i, j
    ! b's centre relative to a's, in A's body frame
    do i = 1, 3
      c(i) = cb(i) - a(i)
    end do
    ! d: offset in a's box frame; e: offset along b's axes
    do i = 1, 3
      d(i) = a(3 + 3*i + 1)*c(1) + a(3 + 3*i + 2)*c(2) + a(3 + 3*i + 3)*c(3)
      e(i) = v(1, i)*c(1) + v(2, i)*c(2) + v(3, i)*c(3)
    end do
    ! along the line of centres L = c/|c|: projections separated by |c| - r_a(L) - r_b(L),
    ! r(L) = sum of half extents times |axis . L|; tight for distant boxes
    s3 = 0.0_dp
    len = sqrt(c(1)*c(1) + c(2)*c(2) + c(3)*c(3))
    if (len > 0.0_dp) then
      s3 = len - 2.0_dp*slack - (a(4)*abs(d(1)) + a(5)*abs(d(2)) + a(6)*abs(d(3)) + &
                                 b(4)*abs(e(1)) + b(5)*abs(e(2)) + b(6)*abs(e(3)))/len
      s3 = max(s3, 0.0_dp)**2
      if (s3 > cutoff) then
        box_gap2_posed = s3
        return
      end if
    end if
    ! m: b's axes in a's box frame
    do j = 1, 3
      do i = 1, 3
        m(i, j) = a(3 + 3*i + 1)*v(1, j) + a(3 + 3*i + 2)*v(2, j) + a(3 + 3*i + 3)*v(3, j)
      end do
    end do
    am = abs(m)
    do i = 1, 3
      g(i) = abs(d(i)) - a(3 + i) - slack - (am(i, 1)*b(4) + am(i, 2)*b(5) + am(i, 3)*b(6))
    end do
    s1 = max(g(1), 0.0_dp)**2 + max(g(2), 0.0_dp)**2 + max(g(3), 0.0_dp)**2
    ! in b's box frame the offset is -e
    do j = 1, 3
      g(j) = abs(e(j)) - b(3 + j) - slack - (am(1, j)*a(4) + am(2, j)*a(5) + am(3, j)*a(6))
    end do
    s2 = max(g(1), 0.0_dp)**2 + max(g(2), 0.0_dp)**2 + max(g(3), 0.0_dp)**2
    box_gap2_posed = max(s1, s2, s3)
  end function box_gap2_posed

  pure real(dp) function sqdist3(x, y)
    real(dp), intent(in) :: x(3), y(3)
    sqdist3 = (x(1) - y(1))**2 + (x(2) - y(2))**2 + (x(3) - y(3))**2
  end function sqdist3

  !> Squared distance from point p to oriented box b (same frame).
  pure real(dp) function point_box_gap2(p, b)
    real(dp), intent(in) :: p(3), b(15)
    real(dp) :: g(3), d(3)
    integer :: i
    d = p - b(1:3)
    do i = 1, 3
      g(i) = max(abs(b(3 + 3*i + 1)*d(1) + b(3 + 3*i + 2)*d(2) + b(3 + 3*i + 3)*d(3)) - b(3 + i), 0.0_dp)
    end do
    point_box_gap2 = g(1)*g(1) + g(2)*g(2) + g(3)*g(3)
  end function point_box_gap2

  !> Distance and closest points between mesh bodies A and B at poses (xa, qa), (xb, qb).
  !> upper_bound [m]: only distances below it are searched for (result%found tells); use it
  !> when only "closer than" matters, e.g. for time of contact. stats, if given, is added to.
  !> hint: the pair of an earlier query of the same two trees (B trees within the cache
  !> sizes only), whose distance now bounds the search; on return the pair found, or kind
  !> FEATURE_NONE. The answer is bitwise the same with or without it (see below).
  subroutine mesh_mesh_distance(tree_a, xa, qa, tree_b, xb, qb, result, stats, upper_bound, hint)
    type(skd_tree_t), intent(in) :: tree_a, tree_b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4)
    type(distance_result_t), intent(out) :: result
    type(query_stats_t), intent(inout), optional :: stats
    real(dp), intent(in), optional :: upper_bound
    type(feature_pair_t), intent(inout), optional :: hint
    type(relative_pose_t) :: rel
    integer :: stack_a(STACK_SIZE), stack_b(STACK_SIZE), top
    real(dp) :: stack_g(STACK_SIZE), best2, g
    real(dp) :: pa(3), pb(3)
    integer :: best_kind, best_sa, best_sb, best_ka, best_kb
    integer(i8) :: n_box, n_leaf, n_prim
    logical :: cached, hinted
    ! B's boxes and faces in A's frame, each transformed once when first reached (a box of
    ! B meets several of A's): for trees of up to CACHE_BOXES boxes, else per visit.
    real(dp) :: cb(3, CACHE_BOXES), vb(3, 3, CACHE_BOXES)
    logical :: box_ready(CACHE_BOXES), slot_ready(CACHE_SLOTS)
    real(dp) :: tb(3, 3, CACHE_SLOTS), nrm_b(3, CACHE_SLOTS), mid_b(3, 3, CACHE_SLOTS)

    rel = make_relative_pose(tree_a%radius, xa, qa, tree_b%radius, xb, qb)
    cached = tree_b%n_boxes <= CACHE_BOXES .and. tree_b%n_faces <= CACHE_SLOTS
    if (cached) then
      box_ready(1:tree_b%n_boxes) = .false.
      slot_ready(1:tree_b%n_faces) = .false.
    end if
    best2 = huge(1.0_dp)
    if (present(upper_bound)) best2 = upper_bound**2
    best_kind = FEATURE_NONE
    best_sa = 0; best_sb = 0; best_ka = 0; best_kb = 0
    pa = 0.0_dp; pb = 0.0_dp
    n_box = 1; n_leaf = 0; n_prim = 0
    ! The hint's pair bounds the answer from above: searching only below a bound a little
    ! larger (1e-12 relative, far above the rounding of any bound the traversal compares
    ! with) prunes what cannot hold the minimum, while every pair at or below the hint's
    ! distance is still visited in the same order and recorded as before: the answer is the
    ! traversal's own first minimum, bitwise, ties included. Should the bound prune
    ! everything after all, the search runs again without it.
    hinted = .false.
    if (present(hint) .and. cached) then
      if (hint%kind /= FEATURE_NONE) then
        g = hint_gap2(hint)
        if (g > 0.0_dp .and. g*(1.0_dp + 1.0e-12_dp) < best2) then
          best2 = g*(1.0_dp + 1.0e-12_dp)
          hinted = .true.
        end if
      end if
    end if
    call traverse()
    if (hinted .and. best_kind == FEATURE_NONE) then
      best2 = huge(1.0_dp)
      if (present(upper_bound)) best2 = upper_bound**2
      call traverse()
    end if

    if (present(stats)) then
      stats%box_pairs = stats%box_pairs + n_box
      stats%leaf_pairs = stats%leaf_pairs + n_leaf
      stats%primitive_tests = stats%primitive_tests + n_prim
    end if
    if (present(hint)) hint = feature_pair_t(best_kind, best_sa, best_ka, best_sb, best_kb)
    if (best_kind == FEATURE_NONE) then
      result%found = .false.
      result%distance = huge(1.0_dp)
      if (present(upper_bound)) result%distance = upper_bound
      return
    end if
    call finish_result(tree_a, xa, qa, tree_b, rel, best2, best_kind, best_sa, best_ka, best_sb, best_kb, &
                       pa, pb, result)

  contains

    !> Depth-first over box pairs from the roots, nearer child first, pruned by best2.
    subroutine traverse()
      integer :: na, nb, la, ra, lb, rb
      real(dp) :: g, g1, g2
      logical :: split_a
      top = 1
      stack_a(1) = 1
      stack_b(1) = 1
      stack_g(1) = gap2(1, 1)
      do while (top > 0)
        na = stack_a(top)
        nb = stack_b(top)
        g = stack_g(top)
        top = top - 1
        if (g >= best2) cycle
        if (tree_a%right(na) == 0 .and. tree_b%right(nb) == 0) then
          n_leaf = n_leaf + 1
          call leaf_pair(na, nb)
          cycle
        end if
        if (tree_a%right(na) == 0) then
          split_a = .false.
        else if (tree_b%right(nb) == 0) then
          split_a = .true.
        else
          split_a = sum(tree_a%box(4:6, na)) >= sum(tree_b%box(4:6, nb))
        end if
        ! Push the farther child first so the nearer is explored first (tightens best2 early).
        if (split_a) then
          la = na + 1
          ra = tree_a%right(na)
          g1 = gap2(la, nb)
          g2 = gap2(ra, nb)
          n_box = n_box + 2
          if (g1 <= g2) then
            call push(ra, nb, g2)
            call push(la, nb, g1)
          else
            call push(la, nb, g1)
            call push(ra, nb, g2)
          end if
        else
          lb = nb + 1
          rb = tree_b%right(nb)
          g1 = gap2(na, lb)
          g2 = gap2(na, rb)
          n_box = n_box + 2
          if (g1 <= g2) then
            call push(na, rb, g2)
            call push(na, lb, g1)
          else
            call push(na, lb, g1)
            call push(na, rb, g2)
          end if
        end if
      end do
    end subroutine traverse

    !> The squared distance of the hint's primitive pair, computed as leaf_pair does (the
    !> same B face in A's frame, the same test, the same arguments); 0 if it names no pair.
    real(dp) function hint_gap2(h)
      type(feature_pair_t), intent(in) :: h
      integer :: region
      real(dp) :: q(3), s, t, c1(3), c2(3), d2
      ! (the squared distance goes to d2, not to the result itself: the function's name as
      ! an actual argument made gfortran build a trampoline, an executable stack)
      hint_gap2 = 0.0_dp
      if (h%sa < 1 .or. h%sa > tree_a%n_faces .or. h%sb < 1 .or. h%sb > tree_b%n_faces) return
      if (h%ka < 0 .or. h%ka > 3 .or. h%kb < 0 .or. h%kb > 3) return
      if (.not. slot_ready(h%sb)) then
        call place_slot(h%sb, h%sb)
        slot_ready(h%sb) = .true.
      end if
      n_prim = n_prim + 1
      d2 = 0.0_dp
      select case (h%kind)
      case (FEATURE_VERTEX_FACE)
        call closest_point_triangle(tree_a%tri(:, h%ka, h%sa), tb(:, 1, h%sb), tb(:, 2, h%sb), tb(:, 3, h%sb), q, &
                                    region, d2)
      case (FEATURE_EDGE_EDGE)
        call closest_segment_segment(tree_a%tri(:, h%ka, h%sa), tree_a%tri(:, mod(h%ka, 3) + 1, h%sa), &
                                     tb(:, h%kb, h%sb), tb(:, mod(h%kb, 3) + 1, h%sb), s, t, c1, c2, d2)
      case (FEATURE_FACE_VERTEX)
        call closest_point_triangle(tb(:, h%kb, h%sb), tree_a%tri(:, 1, h%sa), tree_a%tri(:, 2, h%sa), &
                                    tree_a%tri(:, 3, h%sa), q, region, d2)
      end select
      hint_gap2 = d2
    end function hint_gap2

    !> box_gap2 of box ia of A and box ib of B at the current best2
    real(dp) function gap2(ia, ib)
      integer, intent(in) :: ia, ib
      if (cached) then
        if (.not. box_ready(ib)) then
          call transform_box(tree_b%box(:, ib), rel, cb(:, ib), vb(:, :, ib))
          box_ready(ib) = .true.
        end if
        gap2 = box_gap2_posed(tree_a%box(:, ia), tree_b%box(:, ib), cb(:, ib), vb(:, :, ib), rel%slack, best2)
      else
        gap2 = box_gap2(tree_a%box(:, ia), tree_b%box(:, ib), rel, best2)
      end if
    end function gap2

    subroutine push(ia, ib, gap)
      integer, intent(in) :: ia, ib
      real(dp), intent(in) :: gap
      if (gap >= best2) return
      top = top + 1
      stack_a(top) = ia
      stack_b(top) = ib
      stack_g(top) = gap
    end subroutine push

    !> B's face in slot sb in A's frame, into position j of tb, nrm_b, mid_b.
    subroutine place_slot(sb, j)
      integer, intent(in) :: sb, j
      integer :: k
      do k = 1, 3
        tb(:, k, j) = matmul(rel%r, tree_b%tri(:, k, sb)) + rel%t
      end do
      nrm_b(:, j) = matmul(rel%r, tree_b%normal(:, sb))
      do k = 1, 3
        mid_b(:, k, j) = 0.5_dp*(tb(:, k, j) + tb(:, mod(k, 3) + 1, j))
      end do
    end subroutine place_slot

    subroutine leaf_pair(na, nb)
      integer, intent(in) :: na, nb
      integer :: sa, sb, ka, kb, j, fa0, fa1, fb0, fb1, region, off
      real(dp) :: q(3), d2, s, t, c1(3), c2(3), h, mid_a(3), half_a, reach, reach_a
      fa0 = tree_a%first(na)
      fa1 = fa0 + tree_a%count(na) - 1
      fb0 = tree_b%first(nb)
      fb1 = fb0 + tree_b%count(nb) - 1
      ! B's faces of this leaf are at j = sb - off in tb, nrm_b, mid_b
      if (cached) then
        off = 0
        do sb = fb0, fb1
          if (slot_ready(sb)) cycle
          call place_slot(sb, sb)
          slot_ready(sb) = .true.
        end do
      else
        off = fb0 - 1
        do sb = fb0, fb1
          call place_slot(sb, sb - off)
        end do
      end if
      ! vertices of A against faces of B, edges of A against edges of B
      do sa = fa0, fa1
        do ka = 1, 3
          if (owns_vertex(tree_a%flags(sa), ka)) then
            do sb = fb0, fb1
              j = sb - off
              ! the distance to the face's plane is a lower bound: skip faces it rules out
              h = nrm_b(1, j)*(tree_a%tri(1, ka, sa) - tb(1, 1, j)) + nrm_b(2, j)*(tree_a%tri(2, ka, sa) - tb(2, 1, j)) + &
                  nrm_b(3, j)*(tree_a%tri(3, ka, sa) - tb(3, 1, j))
              if (h*h >= best2) cycle
              call closest_point_triangle(tree_a%tri(:, ka, sa), tb(:, 1, j), tb(:, 2, j), tb(:, 3, j), q, region, d2)
              n_prim = n_prim + 1
              if (d2 < best2) then
                best2 = d2; best_kind = FEATURE_VERTEX_FACE
                best_sa = sa; best_ka = ka; best_sb = sb; best_kb = 0
                pa = tree_a%tri(:, ka, sa); pb = q
              end if
            end do
          end if
          if (owns_edge(tree_a%flags(sa), ka)) then
            mid_a = 0.5_dp*(tree_a%tri(:, ka, sa) + tree_a%tri(:, mod(ka, 3) + 1, sa))
            half_a = tree_a%half_edge(ka, sa)
            ! (best2 only falls in the loop below: a reach from its value here stays safe)
            reach_a = huge(1.0_dp)
            if (best2 < huge(1.0_dp)) reach_a = (1.0_dp + 1.0e-12_dp)*sqrt(best2) + half_a
            do sb = fb0, fb1
              j = sb - off
              do kb = 1, 3
                if (.not. owns_edge(tree_b%flags(sb), kb)) cycle
                ! Two segments are at least |c_a - c_b| - r_a - r_b apart (centres, half
                ! lengths): pairs this rules out skip the exact test (most edge pairs of two
                ! boxes in contact). The margin covers the rounding of the bound, so the
                ! closest pair found is the same as without the test.
                if (reach_a < huge(1.0_dp)) then
                  reach = reach_a + tree_b%half_edge(kb, sb)
                  if (sqdist3(mid_a, mid_b(:, kb, j)) > reach*reach) cycle
                end if
                call closest_segment_segment(tree_a%tri(:, ka, sa), tree_a%tri(:, mod(ka, 3) + 1, sa), &
                                             tb(:, kb, j), tb(:, mod(kb, 3) + 1, j), s, t, c1, c2, d2)
                n_prim = n_prim + 1
                if (d2 < best2) then
                  best2 = d2; best_kind = FEATURE_EDGE_EDGE
                  best_sa = sa; best_ka = ka; best_sb = sb; best_kb = kb
                  pa = c1; pb = c2
                end if
              end do
            end do
          end if
        end do
      end do
      ! vertices of B against faces of A
      do sb = fb0, fb1
        j = sb - off
        do kb = 1, 3
          if (.not. owns_vertex(tree_b%flags(sb), kb)) cycle
          do sa = fa0, fa1
            h = tree_a%normal(1, sa)*(tb(1, kb, j) - tree_a%tri(1, 1, sa)) + &
                tree_a%normal(2, sa)*(tb(2, kb, j) - tree_a%tri(2, 1, sa)) + &
                tree_a%normal(3, sa)*(tb(3, kb, j) - tree_a%tri(3, 1, sa))
            if (h*h >= best2) cycle
            call closest_point_triangle(tb(:, kb, j), tree_a%tri(:, 1, sa), tree_a%tri(:, 2, sa), &
                                        tree_a%tri(:, 3, sa), q, region, d2)
            n_prim = n_prim + 1
            if (d2 < best2) then
              best2 = d2; best_kind = FEATURE_FACE_VERTEX
              best_sa = sa; best_ka = 0; best_sb = sb; best_kb = kb
              pa = q; pb = tb(:, kb, j)
            end if
          end do
        end do
      end do
    end subroutine leaf_pair

  end subroutine mesh_mesh_distance

  !> Fills the result from the best pair found (points pa, pb in A's frame).
  subroutine finish_result(tree_a, xa, qa, tree_b, rel, best2, kind, sa, ka, sb, kb, pa, pb, result)
    type(skd_tree_t), intent(in) :: tree_a, tree_b
    real(dp), intent(in) :: xa(3), qa(4)
    type(relative_pose_t), intent(in) :: rel
    real(dp), intent(in) :: best2, pa(3), pb(3)
    integer, intent(in) :: kind, sa, ka, sb, kb
    type(distance_result_t), intent(inout) :: result
    real(dp) :: ra(3, 3), n(3), length, da(3), db(3)
    ra = quat_to_matrix(qa)
    result%found = .true.
    result%kind = kind
    result%distance = sqrt(best2)
    result%point_a = xa + matmul(ra, pa)
    result%point_b = xa + matmul(ra, pb)
    n = pb - pa
    length = norm2(n)
    if (length > 0.0_dp) then
      n = n/length
    else
      ! Touching: the normal comes from the features themselves.
      select case (kind)
      case (FEATURE_VERTEX_FACE)
        n = -matmul(rel%r, tree_b%normal(:, sb))
      case (FEATURE_FACE_VERTEX)
        n = tree_a%normal(:, sa)
      case default
        da = tree_a%tri(:, mod(ka, 3) + 1, sa) - tree_a%tri(:, ka, sa)
        db = matmul(rel%r, tree_b%tri(:, mod(kb, 3) + 1, sb) - tree_b%tri(:, kb, sb))
        n = cross(da, db)
        length = norm2(n)
        if (length > 0.0_dp) then
          n = n/length
          if (dot_product(n, tree_a%normal(:, sa)) < 0.0_dp) n = -n
        else
          n = tree_a%normal(:, sa)
        end if
      end select
    end if
    result%normal = matmul(ra, n)
    select case (kind)
    case (FEATURE_VERTEX_FACE)
      result%feature_a = [tree_a%tri_nodes(ka, sa), 0]
      result%feature_b = [tree_b%face_id(sb), 0]
    case (FEATURE_FACE_VERTEX)
      result%feature_a = [tree_a%face_id(sa), 0]
      result%feature_b = [tree_b%tri_nodes(kb, sb), 0]
    case default
      result%feature_a = edge_nodes(tree_a, sa, ka)
      result%feature_b = edge_nodes(tree_b, sb, kb)
    end select
  end subroutine finish_result

  pure function edge_nodes(tree, slot, k) result(e)
    type(skd_tree_t), intent(in) :: tree
    integer, intent(in) :: slot, k
    integer :: e(2), i, j
    i = tree%tri_nodes(k, slot)
    j = tree%tri_nodes(mod(k, 3) + 1, slot)
    e = [min(i, j), max(i, j)]
  end function edge_nodes

  !> Reference for tests and benchmarks: every vertex of A against every face of B, every
  !> vertex of B against every face of A, every edge of A against every edge of B, taken
  !> straight from the meshes (unique edges: each face edge with first node < second node,
  !> which lists every edge of a closed, consistently oriented mesh once). Same frame
  !> convention as mesh_mesh_distance. O(n_A n_B).
  subroutine mesh_mesh_distance_brute(mesh_a, xa, qa, mesh_b, xb, qb, result, stats)
    type(mesh_t), intent(in) :: mesh_a, mesh_b
    real(dp), intent(in) :: xa(3), qa(4), xb(3), qb(4)
    type(distance_result_t), intent(out) :: result
    type(query_stats_t), intent(inout), optional :: stats
    type(relative_pose_t) :: rel
    real(dp), allocatable :: nb(:, :)
    integer, allocatable :: ea(:, :), eb(:, :)
    real(dp) :: best2, d2, q(3), s, t, c1(3), c2(3), pa(3), pb(3), ra(3, 3), n(3), length
    integer :: i, f, nea, neb, region, kind, i1, i2
    integer(i8) :: n_prim

    rel = make_relative_pose(0.0_dp, xa, qa, 0.0_dp, xb, qb)
    allocate (nb(3, mesh_b%n_nodes))
    do i = 1, mesh_b%n_nodes
      nb(:, i) = matmul(rel%r, mesh_b%nodes(:, i)) + rel%t
    end do
    call unique_edges(mesh_a, ea, nea)
    call unique_edges(mesh_b, eb, neb)
    best2 = huge(1.0_dp)
    kind = FEATURE_NONE
    n_prim = 0
    do i = 1, mesh_a%n_nodes
      do f = 1, mesh_b%n_faces
        call closest_point_triangle(mesh_a%nodes(:, i), nb(:, mesh_b%faces(1, f)), nb(:, mesh_b%faces(2, f)), &
                                    nb(:, mesh_b%faces(3, f)), q, region, d2)
        n_prim = n_prim + 1
        if (d2 < best2) then
          best2 = d2; kind = FEATURE_VERTEX_FACE
          pa = mesh_a%nodes(:, i); pb = q
          result%feature_a = [i, 0]; result%feature_b = [f, 0]
          n = -mesh_b%face_normal(f)
        end if
      end do
    end do
    do i = 1, mesh_b%n_nodes
      do f = 1, mesh_a%n_faces
        call closest_point_triangle(nb(:, i), mesh_a%nodes(:, mesh_a%faces(1, f)), mesh_a%nodes(:, mesh_a%faces(2, f)), &
                                    mesh_a%nodes(:, mesh_a%faces(3, f)), q, region, d2)
        n_prim = n_prim + 1
        if (d2 < best2) then
          best2 = d2; kind = FEATURE_FACE_VERTEX
          pa = q; pb = nb(:, i)
          result%feature_a = [f, 0]; result%feature_b = [i, 0]
          n = mesh_a%face_normal(f)
        end if
      end do
    end do
    do i1 = 1, nea
      do i2 = 1, neb
        call closest_segment_segment(mesh_a%nodes(:, ea(1, i1)), mesh_a%nodes(:, ea(2, i1)), &
                                     nb(:, eb(1, i2)), nb(:, eb(2, i2)), s, t, c1, c2, d2)
        n_prim = n_prim + 1
        if (d2 < best2) then
          best2 = d2; kind = FEATURE_EDGE_EDGE
          pa = c1; pb = c2
          result%feature_a = ea(:, i1); result%feature_b = eb(:, i2)
          n = cross(mesh_a%nodes(:, ea(2, i1)) - mesh_a%nodes(:, ea(1, i1)), nb(:, eb(2, i2)) - nb(:, eb(1, i2)))
        end if
      end do
    end do
    if (present(stats)) stats%primitive_tests = stats%primitive_tests + n_prim
    ra = quat_to_matrix(qa)
    result%found = kind /= FEATURE_NONE
    result%kind = kind
    result%distance = sqrt(best2)
    result%point_a = xa + matmul(ra, pa)
    result%point_b = xa + matmul(ra, pb)
    length = norm2(pb - pa)
    if (length > 0.0_dp) n = (pb - pa)/length
    length = norm2(n)
    if (length > 0.0_dp) n = n/length
    result%normal = matmul(ra, n)
  end subroutine mesh_mesh_distance_brute

  subroutine unique_edges(m, e, ne)
    type(mesh_t), intent(in) :: m
    integer, allocatable, intent(out) :: e(:, :)
    integer, intent(out) :: ne
    integer :: f, k, i, j
    allocate (e(2, 3*m%n_faces))
    ne = 0
    do f = 1, m%n_faces
      do k = 1, 3
        i = m%faces(k, f)
        j = m%faces(mod(k, 3) + 1, f)
        if (i < j) then
          ne = ne + 1
          e(:, ne) = [i, j]
        end if
      end do
    end do
  end subroutine unique_edges

  !> Spheres of radii ra, rb [m] centred at ca, cb [m] (world). The distance is negative
  !> when they overlap (by that depth). Coincident centres take the normal +z.
  pure subroutine sphere_sphere_distance(ca, ra, cb, rb, result)
    real(dp), intent(in) :: ca(3), ra, cb(3), rb
    type(distance_result_t), intent(out) :: result
    real(dp) :: d(3), length
    d = cb - ca
    length = norm2(d)
    if (length > 0.0_dp) then
      result%normal = d/length
    else
      result%normal = [0.0_dp, 0.0_dp, 1.0_dp]
    end if
    result%found = .true.
    result%kind = FEATURE_SPHERE_SPHERE
    result%distance = length - ra - rb
    result%point_a = ca + ra*result%normal
    result%point_b = cb - rb*result%normal
    result%feature_a = 0
    result%feature_b = 0
  end subroutine sphere_sphere_distance

  !> Sphere A (centre c [m], world; radius [m]) against mesh body B at pose (x, q): the
  !> exact distance from the centre to the surface minus the radius (negative when the
  !> surface cuts into the sphere; a sphere entirely inside B is not detected here).
  !> feature_b is the closest face of B.
  subroutine sphere_mesh_distance(c, radius, tree, x, q, result, stats)
    real(dp), intent(in) :: c(3), radius
    type(skd_tree_t), intent(in) :: tree
    real(dp), intent(in) :: x(3), q(4)
    type(distance_result_t), intent(out) :: result
    type(query_stats_t), intent(inout), optional :: stats
    real(dp) :: rb(3, 3), p(3), best2, d2, g, g1, g2, cl(3), best(3), n(3), length
    integer :: stack(STACK_SIZE), top, k, s, region, best_s, l, r
    real(dp) :: stack_g(STACK_SIZE)
    integer(i8) :: n_box, n_leaf, n_prim
    rb = quat_to_matrix(q)
    p = matmul(transpose(rb), c - x)
    best2 = huge(1.0_dp)
    best_s = 0
    best = 0.0_dp
    n_box = 1; n_leaf = 0; n_prim = 0
    top = 1
    stack(1) = 1
    stack_g(1) = point_box_gap2(p, tree%box(:, 1))
    do while (top > 0)
      k = stack(top)
      g = stack_g(top)
      top = top - 1
      if (g >= best2) cycle
      if (tree%right(k) == 0) then
        n_leaf = n_leaf + 1
        do s = tree%first(k), tree%first(k) + tree%count(k) - 1
          call closest_point_triangle(p, tree%tri(:, 1, s), tree%tri(:, 2, s), tree%tri(:, 3, s), cl, region, d2)
          n_prim = n_prim + 1
          if (d2 < best2) then
            best2 = d2; best = cl; best_s = s
          end if
        end do
        cycle
      end if
      l = k + 1
      r = tree%right(k)
      g1 = point_box_gap2(p, tree%box(:, l))
      g2 = point_box_gap2(p, tree%box(:, r))
      n_box = n_box + 2
      if (g1 <= g2) then
        if (g2 < best2) call push(r, g2)
        if (g1 < best2) call push(l, g1)
      else
        if (g1 < best2) call push(l, g1)
        if (g2 < best2) call push(r, g2)
      end if
    end do
    if (present(stats)) then
      stats%box_pairs = stats%box_pairs + n_box
      stats%leaf_pairs = stats%leaf_pairs + n_leaf
      stats%primitive_tests = stats%primitive_tests + n_prim
    end if
    result%found = .true.
    result%kind = FEATURE_SPHERE_FACE
    length = sqrt(best2)
    if (length > 0.0_dp) then
      n = (best - p)/length
    else
      n = -tree%normal(:, best_s)
    end if
    result%normal = matmul(rb, n)
    result%distance = length - radius
    result%point_b = x + matmul(rb, best)
    result%point_a = c + radius*result%normal
    result%feature_a = 0
    result%feature_b = [tree%face_id(best_s), 0]
  contains
    subroutine push(node, gap)
      integer, intent(in) :: node
      real(dp), intent(in) :: gap
      top = top + 1
      stack(top) = node
      stack_g(top) = gap
    end subroutine push
  end subroutine sphere_mesh_distance

end module mesh_distance
