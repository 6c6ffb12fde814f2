!> Frictionless impulses for a set of simultaneous contacts, with restitution e.
!>
!> Contacts are grouped into connected components through moving bodies (a fixed body does
!> not connect anything). In each group, with velocities scaled by the mass matrix
!> (vt = M^(1/2) v) and E the matrix whose column i is M^(-1/2) J_i^T (J_i: contact i's
!> normal-velocity row), the post-impact velocities are:
!>  - inelastic part: the M-norm projection of v onto {J v >= 0}, i.e. vt + E lambda with
!>    lambda = argmin_{lambda >= 0} |E lambda + vt| (the LCP 0 <= lambda _|_ K lambda + u >= 0,
!>    K = E^T E, u = J v, written as non-negative least squares);
!>  - elastic part: Generalized Reflections (Smith, Kaufman, Vouga, Tamstorf, Grinspun,
!>    "Reflections on Simultaneous Impact", SIGGRAPH 2012): repeatedly solve the e = 1 LCP
!>    0 <= lambda _|_ K lambda + 2 u >= 0 on the contacts still approaching (u_i < -v_tol)
!>    until none approaches; this conserves energy and lets a Newton's cradle break apart;
!>  - v+ = (1 - e) v_inelastic + e v_elastic (generalized restitution). Kinetic energy is
!>    convex, so KE+ <= KE-, with equality at e = 1; momentum is conserved; and since the
!>    projection is unique the answer is symmetric whenever the contact set is: a box landing
!>    flat on four corners gets no spin from the order of its corners.
!>  - Contacts of different e in one group (a ball hit at once by a bouncy and a dead one):
!>    each contact's impulse is blended with its own e, P_i = (1 - e_i) lambda_i +
!>    e_i lambda_elastic_i, so that an isolated contact leaves at -e_i times its approach
!>    speed. Contacts not approaching take the smallest e of those that do (a cradle's
!>    touching balls pass the impact on as the impact's own material). Such a blend is not a
!>    convex combination of the two solutions, so it is kept only if it neither adds kinetic
!>    energy nor leaves a contact approaching; otherwise the group falls back to one e, the
!>    smallest of its approaching contacts (always dissipative).
!> The NNLS solve is exact (Lawson-Hanson), so no iteration order enters the answer.
module impulse_solver
  use kinds, only: dp
  use error_status, only: error_t
  use vector_ops, only: cross
  use quaternion, only: quat_rotate, quat_rotate_inverse
  use body_state, only: bodies_t
  use nnls, only: solve_nnls, nnls_state_t
  use contact_point, only: contact_t
  use islands, only: contact_groups, group_members
  implicit none
  private
  public :: contact_t, impulse_stats_t, resolve_impacts, normal_velocity, normal_curvature, scaled_velocity, &
            set_scaled_velocity, scaled_row, group_members, contact_groups, projection_warm_t

  !> The factorisations of the last inelastic projections of a fixed set of contacts, one
  !> per contact group (contact_groups' order), for repeated solves with the same contacts
  !> and poses and new velocities (the rounds of a staggered solve): each round's
  !> projection starts from the last one's passive set and QR (nnls_state_t).
  type :: projection_warm_t
    type(nnls_state_t), allocatable :: groups(:)
  end type projection_warm_t


  type :: impulse_stats_t
    integer :: groups = 0             !< contact groups solved
    integer :: reflection_rounds = 0  !< generalized-reflection rounds, summed
    integer :: max_rounds_seen = 0
    integer :: cap_hits = 0           !< groups whose elastic loop hit the cap
    integer :: nnls_iterations = 0
    integer :: mixed_groups = 0       !< groups solved with each contact's own e
    integer :: mixed_fallbacks = 0    !< groups of several e that fell back to one (the smallest)
    integer :: nnls_unconverged = 0   !< solves stopped at the cap (feasible, not optimal: the
                                      !< next time of contact catches any leftover approach)
  end type impulse_stats_t

contains

  !> Relative normal velocity at a contact, positive when separating [m/s].
  pure real(dp) function normal_velocity(bodies, c)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: c
    real(dp) :: vb(3), va(3)
    va = point_velocity(bodies, c%a, c%point)
    vb = point_velocity(bodies, c%b, c%point)
    normal_velocity = dot_product(c%normal, vb - va)
  end function normal_velocity

  !> The second time derivative of contact c's gap at the bodies' present velocities, where
  !> the motion is unfavourable [m/s^2]: n.(a_b(p) - a_a(p)) + 2 (w x n).(v_b(p) - v_a(p)), the
  !> material points' accelerations under torque-free turning (centripetal and Euler terms)
  !> and the turning of the normal carried across the relative velocity, with w that of
  !> whichever body makes it the smaller (a vertex-face normal turns with the face's body,
  !> an edge-edge one with both). Translation adds nothing: the pass's velocities hold for the
  !> whole step. The terms of the normal's own second derivative are of order gap times
  !> w^2 and left out.
  pure real(dp) function normal_curvature(bodies, c)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: c
    real(dp) :: v_rel(3), coriolis_a, coriolis_b
    v_rel = point_velocity(bodies, c%b, c%point) - point_velocity(bodies, c%a, c%point)
    coriolis_a = 2.0_dp*dot_product(cross(bodies%w(:, c%a), c%normal), v_rel)
    coriolis_b = 2.0_dp*dot_product(cross(bodies%w(:, c%b), c%normal), v_rel)
    normal_curvature = dot_product(c%normal, point_acceleration(bodies, c%b, c%point) - &
                                   point_acceleration(bodies, c%a, c%point)) + min(coriolis_a, coriolis_b)
  end function normal_curvature

  !> Acceleration of body i's material point at p under torque-free motion at constant
  !> linear velocity: w x (w x r) + alpha x r with alpha = I^-1 ((I w) x w) [m/s^2].
  pure function point_acceleration(bodies, i, p) result(ap)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: p(3)
    real(dp) :: ap(3), r(3), w(3), w_body(3), alpha(3)
    if (bodies%fixed(i)) then
      ap = 0.0_dp
      return
    end if
    r = p - bodies%x(:, i)
    w = bodies%w(:, i)
    w_body = quat_rotate_inverse(bodies%q(:, i), w)
    alpha = quat_rotate(bodies%q(:, i), cross(bodies%inertia(:, i)*w_body, w_body)/bodies%inertia(:, i))
    ap = cross(w, cross(w, r)) + cross(alpha, r)
  end function point_acceleration

  pure function point_velocity(bodies, i, p) result(vp)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: p(3)
    real(dp) :: vp(3)
    vp = bodies%v(:, i) + cross(bodies%w(:, i), p - bodies%x(:, i))
  end function point_velocity

  !> Applies the impulses of every contact group to bodies%v and bodies%w.
  !> velocity_tolerance [m/s]: approach speeds below it count as resting (no reflection);
  !> max_rounds caps the generalized-reflection loop (then the group is made inelastic).
  !> normal_impulse(i), when present: the normal impulse applied at contact i [N s].
  !> max_group, when present: groups of more contacts are not solved here (the dense exact
  !> solve grows as the cube of a group's size); large(i) marks their contacts, for an
  !> iterative solver of the caller's.
  !> warm, when present: the factorisations of the previous call with the same contacts and
  !> poses (made here on the first), the start of each group's projection.
  subroutine resolve_impacts(bodies, contacts, velocity_tolerance, max_rounds, stats, err, normal_impulse, &
                             max_group, large, warm)
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    real(dp), intent(in) :: velocity_tolerance
    integer, intent(in) :: max_rounds
    type(impulse_stats_t), intent(inout) :: stats
    type(error_t), intent(inout) :: err
    real(dp), intent(out), optional :: normal_impulse(:)
    integer, intent(in), optional :: max_group
    logical, intent(out), optional :: large(:)
    type(projection_warm_t), intent(inout), optional :: warm
    real(dp), allocatable :: group_impulse(:)
    integer, allocatable :: group_start(:), group_list(:)
    integer :: n_groups, k, g

    call contact_groups(bodies, contacts, group_start, group_list, n_groups)
    if (present(warm)) then
      if (allocated(warm%groups)) then
        if (size(warm%groups) /= n_groups) deallocate (warm%groups)
      end if
      if (.not. allocated(warm%groups)) allocate (warm%groups(n_groups))
    end if
    if (present(normal_impulse)) normal_impulse = 0.0_dp
    if (present(large)) large = .false.
    do k = 1, n_groups
      associate (in_group => group_list(group_start(k):group_start(k + 1) - 1))
      if (present(max_group) .and. present(large)) then
        if (size(in_group) > max_group) then
          large(in_group) = .true.
          cycle
        end if
      end if
      ! A group none of whose contacts approaches (faster than it may) needs no impulse: the
      ! projection of a velocity already in the cone is itself (one pile touched by one
      ! impact must not pay for the solve of all its resting groups).
      if (any([(normal_velocity(bodies, contacts(in_group(g))) < &
                -contacts(in_group(g))%allowed_approach - velocity_tolerance, g=1, size(in_group))])) then
        allocate (group_impulse(size(in_group)))
        if (present(warm)) then
          call solve_group(bodies, contacts(in_group), velocity_tolerance, max_rounds, stats, group_impulse, err, &
                           warm%groups(k))
        else
          call solve_group(bodies, contacts(in_group), velocity_tolerance, max_rounds, stats, group_impulse, err)
        end if
        if (err%failed()) return
        if (present(normal_impulse)) normal_impulse(in_group) = group_impulse
        deallocate (group_impulse)
      end if
      end associate
    end do
  end subroutine resolve_impacts






  !> One connected group: builds the scaled contact matrix E, solves the inelastic
  !> projection and the elastic reflections, blends them with e.
  subroutine solve_group(bodies, contacts, velocity_tolerance, max_rounds, stats, impulse, err, warm)
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    real(dp), intent(in) :: velocity_tolerance
    integer, intent(in) :: max_rounds
    type(impulse_stats_t), intent(inout) :: stats
    real(dp), intent(out) :: impulse(:)   !< normal impulse of each contact [N s]
    type(error_t), intent(inout) :: err
    type(nnls_state_t), intent(inout), optional :: warm   !< the inelastic projection's factorisation
    real(dp), allocatable :: lambda_elastic(:)
    integer, allocatable :: active(:)
    integer, allocatable :: members(:), side(:, :)
    real(dp), allocatable :: e_matrix(:, :), vt0(:), vt_inelastic(:), vt_elastic(:), lambda(:), u(:)
    logical, allocatable :: approaching(:)
    integer :: n_members, m, i, k, round, iterations
    logical :: converged
    real(dp) :: restitution
    real(dp), allocatable :: e_contact(:), mixed_impulse(:), vt_mixed(:)

    m = size(contacts)
    ! Local numbering of the moving bodies of the group.
    call group_members(bodies, contacts, members, n_members, side)
    allocate (e_matrix(6*n_members, m), vt0(6*n_members))
    e_matrix = 0.0_dp
    do k = 1, n_members
      vt0(6*k - 5:6*k) = scaled_velocity(bodies, members(k))
    end do
    ! Column i: +row for b (the normal points into b), -row for a; fixed bodies have none.
    do i = 1, m
      associate (a => contacts(i)%a, b => contacts(i)%b, sa => side(1, i), sb => side(2, i))
        if (sb > 0) e_matrix(6*sb - 5:6*sb, i) = scaled_row(bodies, b, contacts(i)%point, contacts(i)%normal)
        if (sa > 0) e_matrix(6*sa - 5:6*sa, i) = e_matrix(6*sa - 5:6*sa, i) - &
                                                 scaled_row(bodies, a, contacts(i)%point, contacts(i)%normal)
      end associate
    end do

    ! The group's e: the smallest over the contacts that approach (resting contacts of the
    ! group, neither approaching nor separating, do not make a bouncing impact inelastic).
    u = matmul(transpose(e_matrix), vt0)
    restitution = 0.0_dp
    if (any(u < -velocity_tolerance)) restitution = minval(contacts%restitution, mask=u < -velocity_tolerance)
    ! each contact's own e (those not approaching: the group's)
    e_contact = merge(contacts%restitution, restitution, u < -velocity_tolerance)

    ! Inelastic projection over all contacts of the group.
    allocate (lambda(m), lambda_elastic(m))
    lambda_elastic = 0.0_dp
    if (any(contacts%allowed_approach /= 0.0_dp)) then
      call solve_biased_projection(e_matrix, vt0, contacts%allowed_approach, lambda, iterations, err, converged, warm)
    else
      call solve_nnls(e_matrix, -vt0, lambda, iterations, err, converged, state=warm)
    end if
    if (err%failed()) return
    if (.not. converged) stats%nnls_unconverged = stats%nnls_unconverged + 1
    stats%nnls_iterations = stats%nnls_iterations + iterations
    vt_inelastic = vt0 + matmul(e_matrix, lambda)

    ! Generalized reflections (e = 1) on the contacts still approaching.
    vt_elastic = vt0
    if (any(e_contact > 0.0_dp)) then
      allocate (approaching(m))
      do round = 1, max_rounds + 1
        u = matmul(transpose(e_matrix), vt_elastic)
        approaching = u < -velocity_tolerance
        if (.not. any(approaching)) exit
        if (round > max_rounds) then
          stats%cap_hits = stats%cap_hits + 1
          vt_elastic = vt_inelastic
          lambda_elastic = lambda
          exit
        end if
        stats%reflection_rounds = stats%reflection_rounds + 1
        stats%max_rounds_seen = max(stats%max_rounds_seen, round)
        block
          real(dp), allocatable :: sub(:, :), sub_lambda(:)
          active = pack([(i, i=1, m)], approaching)
          sub = e_matrix(:, active)
          allocate (sub_lambda(size(sub, 2)))
          call solve_nnls(sub, -2.0_dp*vt_elastic, sub_lambda, iterations, err, converged)
          if (err%failed()) return
          if (.not. converged) stats%nnls_unconverged = stats%nnls_unconverged + 1
          stats%nnls_iterations = stats%nnls_iterations + iterations
          vt_elastic = vt_elastic + matmul(sub, sub_lambda)
          lambda_elastic(active) = lambda_elastic(active) + sub_lambda
        end block
      end do
    end if

    if (any(e_contact /= restitution)) then
      mixed_impulse = (1.0_dp - e_contact)*lambda + e_contact*lambda_elastic
      vt_mixed = vt0 + matmul(e_matrix, mixed_impulse)
      u = matmul(transpose(e_matrix), vt_mixed)
      ! (energy to 1e-12 relative: rounding of the sums, far below any physical gain)
      if (dot_product(vt_mixed, vt_mixed) <= dot_product(vt0, vt0)*(1.0_dp + 1.0e-12_dp) .and. &
          all(u >= -contacts%allowed_approach - velocity_tolerance)) then
        impulse = mixed_impulse
        do k = 1, n_members
          call set_scaled_velocity(bodies, members(k), vt_mixed(6*k - 5:6*k))
        end do
        stats%groups = stats%groups + 1
        stats%mixed_groups = stats%mixed_groups + 1
        return
      end if
      stats%mixed_fallbacks = stats%mixed_fallbacks + 1
    end if
    vt0 = (1.0_dp - restitution)*vt_inelastic + restitution*vt_elastic
    impulse = (1.0_dp - restitution)*lambda + restitution*lambda_elastic
    do k = 1, n_members
      call set_scaled_velocity(bodies, members(k), vt0(6*k - 5:6*k))
    end do
    stats%groups = stats%groups + 1
  end subroutine solve_group

  !> The inelastic projection with speculative contacts: the velocity closest to vt0 (in the
  !> mass norm) with u_i = E_i^T vt >= -s_i, s the allowed approach speeds. Its dual is the
  !> bound-constrained problem min_{lambda >= 0} lambda^T K lambda / 2 + lambda^T (u0 + s),
  !> which is non-negative least squares once rows eps I are appended to E and -s/eps to the
  !> right-hand side: |E lambda + vt0|^2 + |eps lambda + s/eps|^2 is the dual's objective
  !> (times two, plus a constant) plus eps^2 |lambda|^2. With eps^2 a 1e-10 fraction of the
  !> largest diagonal of K the constraints hold to 1e-10 of the velocity change, below the
  !> solvers' tolerances (a larger eps loses digits of s/eps in the residual), and
  !> the appended rows make the problem full rank (no dependent columns held out).
  subroutine solve_biased_projection(e_matrix, vt0, allowed, lambda, iterations, err, converged, warm)
    real(dp), intent(in) :: e_matrix(:, :), vt0(:), allowed(:)
    real(dp), intent(out) :: lambda(:)
    integer, intent(out) :: iterations
    type(error_t), intent(inout) :: err
    logical, intent(out) :: converged
    type(nnls_state_t), intent(inout), optional :: warm
    real(dp), allocatable :: augmented(:, :), rhs(:)
    real(dp) :: eps
    integer :: rows, m, i
    rows = size(e_matrix, 1)
    m = size(e_matrix, 2)
    eps = 1.0e-5_dp*sqrt(maxval(sum(e_matrix**2, dim=1)))
    allocate (augmented(rows + m, m), rhs(rows + m))
    augmented = 0.0_dp
    augmented(1:rows, :) = e_matrix
    rhs(1:rows) = -vt0
    do i = 1, m
      augmented(rows + i, i) = eps
      rhs(rows + i) = -allowed(i)/eps
    end do
    call solve_nnls(augmented, rhs, lambda, iterations, err, converged, state=warm)
  end subroutine solve_biased_projection

  !> M^(1/2) (v, w): sqrt(m) v and R diag(sqrt(I)) R^T w.
  pure function scaled_velocity(bodies, i) result(vt)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp) :: vt(6)
    vt(1:3) = sqrt(bodies%mass(i))*bodies%v(:, i)
    vt(4:6) = quat_rotate(bodies%q(:, i), sqrt(bodies%inertia(:, i))*quat_rotate_inverse(bodies%q(:, i), bodies%w(:, i)))
  end function scaled_velocity

  subroutine set_scaled_velocity(bodies, i, vt)
    type(bodies_t), intent(inout) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: vt(6)
    bodies%v(:, i) = vt(1:3)/sqrt(bodies%mass(i))
    bodies%w(:, i) = quat_rotate(bodies%q(:, i), quat_rotate_inverse(bodies%q(:, i), vt(4:6))/sqrt(bodies%inertia(:, i)))
  end subroutine set_scaled_velocity

  !> M^(-1/2) J_i^T for body i's part of a contact at p with normal n (as seen by the body
  !> the normal points into): (n / sqrt(m), R diag(I^-1/2) R^T (r x n)).
  pure function scaled_row(bodies, i, p, n) result(row)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: p(3), n(3)
    real(dp) :: row(6)
    row(1:3) = n/sqrt(bodies%mass(i))
    row(4:6) = quat_rotate(bodies%q(:, i), quat_rotate_inverse(bodies%q(:, i), cross(p - bodies%x(:, i), n)) &
                           /sqrt(bodies%inertia(:, i)))
  end function scaled_row

end module impulse_solver
