!> Geometry of one pair of posed bodies, as every contact stage needs it: the gap and
!> normal (analytic for sphere pairs, SKD-tree closest points otherwise), a cheap lower bound
!> on the gap, and the contact points of a pair within a tolerance band, each with a key
!> naming its features (so that a contact can be recognised at the next step).
module pair_geometry
  use kinds, only: dp, i8
  use shape, only: shape_library_t, SHAPE_SPHERE, SHAPE_MESH
  use convex_distance, only: convex_bound_t, convex_lower_bound, max_support_vertices
  use body_state, only: bodies_t
  use mesh_distance, only: distance_result_t, mesh_mesh_distance, sphere_mesh_distance, feature_pair_t
  use contact_features, only: contact_feature_t, find_contact_features
  use impulse_solver, only: contact_t
  use quaternion, only: quat_rotate_inverse
  implicit none
  private
  public :: pair_gap, gap_lower_bound, point_box_gap, pair_contact_points, bounding_sphere_boxes, KEY_LENGTH
  public :: convex_pair, convex_pair_bound

  !> GJK stops when its lower and upper bounds agree to this (relative), or after
  !> gjk_iterations support points (6.3 on average for boxes, tests/unit/test_convex_distance)
  real(dp), parameter :: gjk_rel_tol = 1.0e-12_dp
  integer, parameter :: gjk_iterations = 32

  !> A contact's key: global ids of a and b, the feature kind and the two features' ids.
  integer, parameter :: KEY_LENGTH = 7

contains

  !> Axis-aligned boxes [m] of the bounding spheres of bodies 1:n (centre of mass +- the
  !> shape's bounding radius): they do not change when a body turns, which is what the
  !> grid passes need.
  pure subroutine bounding_sphere_boxes(shapes, bodies, n, lower, upper)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: n
    real(dp), intent(out) :: lower(:, :), upper(:, :)
    integer :: i
    real(dp) :: r
    do i = 1, n
      r = shapes%shapes(bodies%shape_id(i))%bounding_radius
      lower(:, i) = bodies%x(:, i) - r
      upper(:, i) = bodies%x(:, i) + r
    end do
  end subroutine bounding_sphere_boxes

  !> Gap and unit normal (from i to j) between two posed bodies.
  !> hint: for two meshes, the primitive pair of an earlier query of i and j, which speeds
  !> the search without changing its answer (mesh_mesh_distance); updated.
  subroutine pair_gap(shapes, bodies, i, j, xi, qi, xj, qj, gap, normal, hint)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    real(dp), intent(in) :: xi(3), qi(4), xj(3), qj(4)
    real(dp), intent(out) :: gap, normal(3)
    type(feature_pair_t), intent(inout), optional :: hint
    type(distance_result_t) :: d
    real(dp) :: between(3)
    associate (si => shapes%shapes(bodies%shape_id(i)), sj => shapes%shapes(bodies%shape_id(j)))
      if (si%kind == SHAPE_SPHERE .and. sj%kind == SHAPE_SPHERE) then
        between = xj - xi
        gap = norm2(between) - si%radius - sj%radius
        normal = between/norm2(between)
      else if (si%kind == SHAPE_SPHERE) then
        call sphere_mesh_distance(xi, si%radius, sj%tree, xj, qj, d)
        gap = d%distance
        normal = d%normal
      else if (sj%kind == SHAPE_SPHERE) then
        call sphere_mesh_distance(xj, sj%radius, si%tree, xi, qi, d)
        gap = d%distance
        normal = -d%normal
      else
        call mesh_mesh_distance(si%tree, xi, qi, sj%tree, xj, qj, d, hint=hint)
        gap = d%distance
        normal = d%normal
      end if
    end associate
  end subroutine pair_gap

  !> Bodies i and j are both convex meshes small enough for GJK's bound (convex_distance):
  !> where only a lower bound on their gap is needed, convex_pair_bound gives one.
  pure logical function convex_pair(shapes, bodies, i, j)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    associate (si => shapes%shapes(bodies%shape_id(i)), sj => shapes%shapes(bodies%shape_id(j)))
      convex_pair = si%kind == SHAPE_MESH .and. sj%kind == SHAPE_MESH .and. si%convex .and. sj%convex
      if (convex_pair) convex_pair = si%mesh%n_nodes <= max_support_vertices .and. &
                                     sj%mesh%n_nodes <= max_support_vertices
    end associate
  end function convex_pair

  !> A certified lower bound on the gap of a convex pair (convex_pair) at the given poses and
  !> the unit direction (from i to j) along which they are that far apart: GJK's
  !> (convex_distance). certified = .false. when GJK cannot show them apart (touching hulls):
  !> the caller then needs pair_gap.
  pure subroutine convex_pair_bound(shapes, bodies, i, j, xi, qi, xj, qj, gap, normal, certified)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    real(dp), intent(in) :: xi(3), qi(4), xj(3), qj(4)
    real(dp), intent(out) :: gap, normal(3)
    logical, intent(out) :: certified
    type(convex_bound_t) :: bound
    call convex_lower_bound(shapes%shapes(bodies%shape_id(i))%mesh%nodes, xi, qi, &
                            shapes%shapes(bodies%shape_id(j))%mesh%nodes, xj, qj, gjk_rel_tol, gjk_iterations, bound)
    certified = bound%certified
    gap = bound%lower
    normal = bound%normal
  end subroutine convex_pair_bound

  !> A cheap lower bound on the gap between two posed bodies: the larger of (centre distance
  !> minus both bounding radii) and (distance from one body's centre to the other's bounding
  !> box in that body's principal frame, minus the first one's bounding radius). The second
  !> matters for walls and floors, whose bounding spheres are huge.
  !> turn_i, turn_j [m], when present: how far turning can move any surface point of each body
  !> over the time the bound must hold for (Omega R h); the bounding spheres do not turn,
  !> but a body's box turns with it, so its box test gives up that much.
  pure real(dp) function gap_lower_bound(shapes, bodies, i, j, enough, turn_i, turn_j) result(bound)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    real(dp), intent(in) :: enough   !< a bound above this already settles the question
    real(dp), intent(in), optional :: turn_i, turn_j
    real(dp) :: slack_i, slack_j
    slack_i = 0.0_dp
    slack_j = 0.0_dp
    if (present(turn_i)) slack_i = turn_i
    if (present(turn_j)) slack_j = turn_j
    associate (si => shapes%shapes(bodies%shape_id(i)), sj => shapes%shapes(bodies%shape_id(j)))
      bound = norm2(bodies%x(:, j) - bodies%x(:, i)) - si%bounding_radius - sj%bounding_radius
      if (bound > enough) return
      ! the box tests only help where a body is much larger than its partner
      if (si%kind == SHAPE_SPHERE .and. sj%kind == SHAPE_SPHERE) return
      bound = max(bound, point_box_gap(bodies%x(:, i), bodies%x(:, j), bodies%q(:, j), sj%aabb_lower, sj%aabb_upper) &
                  - si%bounding_radius - slack_j)
      bound = max(bound, point_box_gap(bodies%x(:, j), bodies%x(:, i), bodies%q(:, i), si%aabb_lower, si%aabb_upper) &
                  - sj%bounding_radius - slack_i)
    end associate
  end function gap_lower_bound

  !> Distance from point p to a box given in a body's principal frame (body at x, q).
  pure real(dp) function point_box_gap(p, x, q, lower, upper)
    real(dp), intent(in) :: p(3), x(3), q(4), lower(3), upper(3)
    real(dp) :: local(3), outside(3)
    local = quat_rotate_inverse(q, p - x)
    outside = max(lower - local, 0.0_dp, local - upper)
    point_box_gap = norm2(outside)
  end function point_box_gap

  !> Contact points of bodies i and j at their current poses, given their gap and normal:
  !> a pair with a sphere has one point, in the middle of the gap on the normal; two meshes
  !> have one point per contact feature (vertex-face, face-vertex, edge-edge) within
  !> gap + band. Appends to contacts(1:n_contacts) (grown as needed) and keys.
  !> search [m], when present: features within gap + search instead (speculative contacts of
  !> features that may touch within a step); points are still merged within band only.
  subroutine pair_contact_points(shapes, bodies, i, j, gap, normal, band, contacts, keys, n_contacts, features, search)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    real(dp), intent(in) :: gap, normal(3), band
    type(contact_t), allocatable, intent(inout) :: contacts(:)
    integer(i8), allocatable, intent(inout) :: keys(:, :)
    integer, intent(inout) :: n_contacts
    type(contact_feature_t), allocatable, intent(inout) :: features(:)
    real(dp), intent(in), optional :: search
    integer :: f, n_features, first, k
    real(dp) :: p(3), within
    within = band
    if (present(search)) within = max(band, search)
    associate (si => shapes%shapes(bodies%shape_id(i)), sj => shapes%shapes(bodies%shape_id(j)))
      if (si%kind == SHAPE_SPHERE) then
        p = bodies%x(:, i) + (si%radius + 0.5_dp*gap)*normal
        call push(contact_t(a=i, b=j, point=p, normal=normal, gap=gap), [0_i8, 0_i8, 0_i8, 0_i8, 0_i8])
      else if (sj%kind == SHAPE_SPHERE) then
        ! b is the sphere: its surface point towards a, then half the gap back
        p = bodies%x(:, j) - (sj%radius + 0.5_dp*gap)*normal
        call push(contact_t(a=i, b=j, point=p, normal=normal, gap=gap), [0_i8, 0_i8, 0_i8, 0_i8, 0_i8])
      else
        call find_contact_features(si%tree, bodies%x(:, i), bodies%q(:, i), sj%tree, bodies%x(:, j), bodies%q(:, j), &
                                   gap + within, features, n_features)
        first = n_contacts + 1
        do f = 1, n_features
          p = 0.5_dp*(features(f)%point_a + features(f)%point_b)
          ! Faces touching faces meet at the same points from both sides (a corner of A on
          ! B's face and a corner of B on A's face, the edges through them): keep one point
          ! per place, since repeated rows only slow the contact solvers down.
          if (n_contacts >= first) then
            if (any([(norm2(contacts(k)%point - p) <= band .and. dot_product(contacts(k)%normal, features(f)%normal) > 0.999_dp, k=first, n_contacts)])) cycle
          end if
          call push(contact_t(a=i, b=j, point=p, normal=features(f)%normal, gap=features(f)%distance), &
                    int([features(f)%kind, features(f)%feature_a, features(f)%feature_b], i8))
        end do
      end if
    end associate
  contains
    subroutine push(c, feature_key)
      type(contact_t), intent(in) :: c
      integer(i8), intent(in) :: feature_key(KEY_LENGTH - 2)
      type(contact_t), allocatable :: grown(:)
      integer(i8), allocatable :: grown_keys(:, :)
      if (.not. allocated(contacts)) allocate (contacts(16), keys(KEY_LENGTH, 16))
      if (n_contacts == size(contacts)) then
        allocate (grown(2*size(contacts)), grown_keys(KEY_LENGTH, 2*size(contacts)))
        grown(1:n_contacts) = contacts(1:n_contacts)
        grown_keys(:, 1:n_contacts) = keys(:, 1:n_contacts)
        call move_alloc(grown, contacts)
        call move_alloc(grown_keys, keys)
      end if
      n_contacts = n_contacts + 1
      contacts(n_contacts) = c
      keys(:, n_contacts) = [bodies%gid(i), bodies%gid(j), feature_key]
    end subroutine push
  end subroutine pair_contact_points

end module pair_geometry
