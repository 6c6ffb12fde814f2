!> Resting contact: the contact pass at the start of every step (Guendelman, Bridson and
!> Fedkiw 2003, "Nonconvex rigid bodies with stacking", with the step kept whole as in
!> velocity-level time stepping; docs/contact.md, "Resting contact").
!>
!> Contacts in the contact band that are not approaching faster than the rest speed are
!> *persistent*. For the bodies they touch, gravity's impulse over the coming step h is
!> added (v* = v + g h) and the persistent contacts are solved at velocity level with e = 0
!> and Coulomb friction, so that no persistent contact approaches. A body the contacts push
!> then moves over the step at its new velocity and angular velocity, with no further
!> acceleration (symplectic Euler: velocities exact for constant forces, positions first
!> order). Both velocities change at the start of the step, so every contact point's
!> velocity is the solved one throughout the step, never an approaching mixture. A body at
!> rest on a floor therefore moves not at all: conservative advancement sees no closing
!> motion and the step stays at dt_max instead of collapsing into micro-bounces. (Spreading
!> the linear impulse over the step as a constant force is exact for positions too, but
!> the angular impulse cannot be spread under the torque-free exact rotation, and the mix
!> makes rotating bodies' contact points approach at the step's start.)
!>
!> Solvers: a frictionless group of up to exact_limit contacts gets the exact inelastic
!> projection of impulse_solver (the original method, order-free and symmetric); groups
!> with friction or more contacts get projected Gauss-Seidel (contact_solver), contacts
!> ordered bottom-up along gravity and warm-started from the previous step's contact forces
!> (cached by the two bodies' global ids and the features' ids).
!> Nothing here is needed for safety: conservative advancement still bounds every motion,
!> so an unconverged solve costs events, never an interpenetration.
module resting_contact
  use kinds, only: dp, i8
  use error_status, only: error_t
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use impulse_solver, only: contact_t, impulse_stats_t, resolve_impacts, normal_velocity, normal_curvature, &
                            contact_groups, scaled_velocity, set_scaled_velocity, scaled_row, group_members, &
                            projection_warm_t
  use contact_solver, only: pgs_stats_t, pgs_setup_t, solve_contacts_pgs, tangent_basis
  use nnls, only: solve_nnls
  use vector_ops, only: cross
  use sorting, only: sort_index_real, sort_index_keys, find_key
  use warm_start_cache, only: warm_cache_t
  implicit none
  private
  public :: resting_contact_t, resting_stats_t

  !> Groups whose contacts all move slower than this are tried held still (try_sticking)
  !> [m/s]: sliding contacts could not be stopped inside their cones anyway, and the
  !> least-squares solve would be wasted on them.
  real(dp), parameter :: stick_speed = 2.0e-2_dp

  type :: resting_stats_t
    integer(i8) :: passes = 0          !< steps with persistent contacts
    integer(i8) :: contacts = 0        !< persistent contact points solved, summed over steps
    integer(i8) :: loaded = 0          !< body-steps carried by a contact force
    integer(i8) :: warm_starts = 0     !< contacts warm-started from the previous step
    integer(i8) :: projections = 0     !< PGS results finished by the exact projection
    integer(i8) :: staggered_rounds = 0   !< rounds of staggered projections, summed
    integer(i8) :: staggered_solves = 0   !< groups solved by staggered projections
    integer(i8) :: staggered_capped = 0   !< of those, stopped by the round cap (not converged)
    integer(i8) :: stuck = 0              !< groups brought to rest exactly by try_sticking
    integer(i8) :: turning_repairs = 0    !< groups projected again for their turning (repair_turning)
    integer(i8) :: turning_rounds = 0     !< their projections, summed
    integer(i8) :: turning_left = 0       !< of those groups, still late after the last round
  end type resting_stats_t

  type :: resting_contact_t
    real(dp) :: tolerance = 1.0e-9_dp      !< PGS: velocity change per sweep that ends it [m/s]
    integer :: max_sweeps = 200            !< PGS sweep cap (the exact projection finishes)
    integer :: exact_limit = 64            !< largest frictionless group solved exactly
    integer :: projection_limit = 256      !< largest group solved by staggered projections, or projected after PGS
    real(dp) :: velocity_tolerance = 1.0e-9_dp   !< [m/s]
    !> repair_turning: how far below its aim a contact may end the step before it is
    !> projected again [m] (a part of the room between the aim and the settling floor)
    real(dp) :: turning_slack = 0.0_dp
    integer(i8), allocatable :: cache_keys(:, :) !< sorted keys of the last PGS contacts
    real(dp), allocatable :: cache_force(:, :)   !< their contact forces, world [N]
    integer :: n_cache = 0
    !> The local event loop: warm starts kept across the passes of different islands
    !> (persistent), each used if written at or after warm_since [s] (its previous step).
    logical :: persistent = .false.
    real(dp) :: warm_since = -huge(1.0_dp)
    real(dp) :: warm_now = 0.0_dp         !< the time this pass's forces are written at [s]
    type(warm_cache_t) :: warm
    real(dp), allocatable :: dv(:, :), dw(:, :)  !< velocity changes the last pass gave [m/s, rad/s]
    logical, allocatable :: involved(:)          !< work array of resolve: false between calls
    type(resting_stats_t) :: stats
    type(pgs_stats_t) :: pgs
    type(impulse_stats_t) :: exact
  contains
    procedure :: solve => resting_solve
    procedure :: remap_bodies => resting_remap_bodies
    procedure :: forget => resting_forget
  end type resting_contact_t

contains

  !> Drops the warm starts (at checkpoints, so a restart repeats the same arithmetic).
  subroutine resting_forget(self)
    class(resting_contact_t), intent(inout) :: self
    self%n_cache = 0
    call self%warm%clear()
  end subroutine resting_forget

  !> The contact pass over the persistent contacts(1:n) (keys: pair_geometry's) for a step
  !> of h [s] under gravity [m/s^2]: sets the loads of the free-flight propagator and the
  !> angular velocities; linear velocities are left at their start-of-step values.
  !> island, when present: the bodies this pass is for (an island of the local event loop);
  !> those of them in no persistent contact fly free from now (default: every owned body).
  !> The cost is that of the contacts and members, never of the whole scene.
  subroutine resting_solve(self, bodies, flight, contacts, keys, n, h, gravity, err, island)
    class(resting_contact_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    type(contact_t), intent(inout) :: contacts(:)
    integer(i8), intent(in) :: keys(:, :)
    integer, intent(in) :: n
    real(dp), intent(in) :: h, gravity(3)
    type(error_t), intent(inout) :: err
    integer, intent(in), optional :: island(:)
    real(dp), allocatable :: v_start(:, :), w_start(:, :), impulse(:, :), height(:), new_force(:, :), extra(:), &
                             held_impulse(:, :)
    logical, allocatable :: still(:), loaded(:)
    logical :: stuck
    integer(i8), allocatable :: new_keys(:, :)
    type(contact_t), allocatable :: group(:)
    integer, allocatable :: group_start(:), group_list(:), members(:), order(:), moving(:), side(:, :)
    integer :: n_bodies, c, i, g, k, slot, n_new, n_groups, n_moving, m
    real(dp) :: dv(3), down(3), warm_force(3)
    logical :: warm_found

    n_bodies = bodies%n_owned + bodies%n_ghost
    call ensure_involved(self, n_bodies)
    ! the moving bodies of the contacts, once each (local numbering: no table of the scene)
    call group_members(bodies, contacts(1:n), moving, n_moving, side)
    do k = 1, n_moving
      self%involved(moving(k)) = .true.
    end do
    if (n > 0) then
      self%stats%passes = self%stats%passes + 1
      self%stats%contacts = self%stats%contacts + n
    end if
    allocate (v_start(3, n_moving), w_start(3, n_moving))
    do k = 1, n_moving
      v_start(:, k) = bodies%v(:, moving(k))
      w_start(:, k) = bodies%w(:, moving(k))
    end do
    ! which contacts are still at the step's start (before gravity's impulse): a group all of
    ! whose contacts are is first tried as a whole held still (try_sticking)
    allocate (still(n))
    do c = 1, n
      still(c) = norm2(relative_velocity(bodies, contacts(c))) <= stick_speed
    end do
    do k = 1, n_moving
      i = moving(k)
      bodies%v(:, i) = bodies%v(:, i) + h*gravity
    end do

    ! Groups: contacts connected through moving bodies.
    call contact_groups(bodies, contacts(1:n), group_start, group_list, n_groups)
    down = 0.0_dp
    if (norm2(gravity) > 0.0_dp) down = gravity/norm2(gravity)
    allocate (new_keys(size(keys, 1), n), new_force(3, n))
    n_new = 0
    do g = 1, n_groups
      members = group_list(group_start(g):group_start(g + 1) - 1)
      if (all(contacts(members)%friction <= 0.0_dp) .and. size(members) <= self%exact_limit) then
        contacts(members)%restitution = 0.0_dp
        call resolve_impacts(bodies, contacts(members), self%velocity_tolerance, 1, self%exact, err)
        if (err%failed()) return
        cycle
      end if
      ! bottom-up: the lowest contact points first
      allocate (height(size(members)))
      do k = 1, size(members)
        height(k) = -dot_product(down, contacts(members(k))%point)
      end do
      call sort_index_real(height, order)
      members = members(order)
      deallocate (height)
      allocate (impulse(3, size(members)))
      impulse = 0.0_dp
      do k = 1, size(members)
        if (self%persistent) then
          call self%warm%lookup(keys(:, members(k)), self%warm_since, warm_force, warm_found)
          if (warm_found) then
            impulse(:, k) = warm_force*h
            self%stats%warm_starts = self%stats%warm_starts + 1
          end if
          cycle
        end if
        slot = 0
        if (self%n_cache > 0) slot = find_key(self%cache_keys, self%n_cache, keys(:, members(k)))
        if (slot > 0) then
          impulse(:, k) = self%cache_force(:, slot)*h
          self%stats%warm_starts = self%stats%warm_starts + 1
        end if
      end do
      ! A group at rest at the step's start stays at rest if static friction can hold it: tried
      ! first, it spares the iterative solves below (a resting stack costs one least-squares
      ! solve per step instead of up to 60 rounds of staggered projections).
      stuck = .false.
      if (size(members) <= self%projection_limit .and. any(contacts(members)%friction > 0.0_dp) .and. &
          all(still(members))) then
        group = contacts(members)
        held_impulse = 0.0_dp*impulse
        call try_sticking(self, bodies, group, held_impulse, [(.true., k=1, size(members))], err, stuck)
        if (err%failed()) return
        if (stuck) impulse = held_impulse
      end if
      if (stuck) then
        continue
      ! Staggered projections carry the load of a stack through its levels at once; one body
      ! on static ground has no levels, and the joint per-contact solve converges in a few
      ! sweeps there (and matched the incline and sliding-stop solutions to 1e-14).
      else if (size(members) <= self%projection_limit .and. any(contacts(members)%friction > 0.0_dp) .and. &
          moving_bodies(bodies, contacts(members)) > 1) then
        group = contacts(members)
        call staggered_solve(self, bodies, group, impulse, err)
        if (err%failed()) return
      else
        call solve_contacts_pgs(bodies, contacts(members), impulse, self%tolerance, self%max_sweeps, self%pgs)
      end if
      ! PGS converges slowly in tall stacks; what it leaves approaching is removed by the
      ! exact inelastic projection (it changes the velocities by no more than the residual),
      ! so the step is not cut by a micro-event. Larger groups leave it to the events.
      if (size(members) <= self%projection_limit .and. .not. stuck) then
        if (any([(normal_velocity(bodies, contacts(members(k))) < &
                  -contacts(members(k))%allowed_approach - self%velocity_tolerance, k=1, size(members))])) then
          contacts(members)%restitution = 0.0_dp
          allocate (extra(size(members)))
          call resolve_impacts(bodies, contacts(members), self%velocity_tolerance, 1, self%exact, err, extra)
          if (err%failed()) return
          ! the warm start of the next step is the whole answer, projection included
          do k = 1, size(members)
            impulse(:, k) = impulse(:, k) + extra(k)*contacts(members(k))%normal
          end do
          deallocate (extra)
          self%stats%projections = self%stats%projections + 1
        end if
        ! nearly at rest after the iterative solve: the loaded contacts held still, exactly
        if (any(contacts(members)%friction > 0.0_dp)) then
          group = contacts(members)
          loaded = [(dot_product(impulse(:, k), group(k)%normal) > 0.0_dp, k=1, size(members))]
          if (all([(norm2(relative_velocity(bodies, group(k))) <= stick_speed .or. .not. loaded(k), &
                    k=1, size(members))])) then
            call try_sticking(self, bodies, group, impulse, loaded, err, stuck)
            if (err%failed()) return
          end if
        end if
      end if
      if (.not. stuck) then
        call repair_turning(self, bodies, contacts, members, impulse, h, err)
        if (err%failed()) return
      end if
      do k = 1, size(members)
        n_new = n_new + 1
        new_keys(:, n_new) = keys(:, members(k))
        new_force(:, n_new) = impulse(:, k)/h
      end do
      deallocate (impulse)
    end do
    if (self%persistent) then
      ! kept beside the other islands' forces (entries older than this island's previous
      ! step are of no use to anyone)
      do k = 1, n_new
        call self%warm%store(new_keys(:, k), new_force(:, k), self%warm_now, self%warm_since)
      end do
    else
      ! The new cache, sorted by key.
      call sort_index_keys(new_keys(:, 1:n_new), order)
      if (allocated(self%cache_keys)) deallocate (self%cache_keys, self%cache_force)
      self%cache_keys = new_keys(:, order)
      self%cache_force = new_force(:, order)
      self%n_cache = n_new
    end if

    ! A body in a persistent contact keeps its new velocity and moves at it over the step
    ! (its gravity for the step is already in it): zero acceleration, released to re-anchor.
    ! All of them, pushed or not: a body left on its parabola would start the step slower
    ! by g h than one beside it, and their contact would approach at the step's start.
    ! Bodies in no persistent contact fly on their exact parabolas.
    if (allocated(self%dv)) then
      if (size(self%dv, 2) < n_bodies) deallocate (self%dv, self%dw)
    end if
    if (.not. allocated(self%dv)) allocate (self%dv(3, n_bodies), self%dw(3, n_bodies))
    if (present(island)) then
      do m = 1, size(island)
        i = island(m)
        if (i > bodies%n_owned .or. bodies%fixed(i)) cycle
        if (.not. self%involved(i)) call flight%clear_load(i)
      end do
    else
      do i = 1, bodies%n_owned
        if (bodies%fixed(i)) cycle
        if (.not. self%involved(i)) call flight%clear_load(i)
      end do
    end if
    do k = 1, n_moving
      i = moving(k)
      self%involved(i) = .false.
      if (i > bodies%n_owned) cycle
      dv = bodies%v(:, i) - (v_start(:, k) + h*gravity)
      self%dv(:, i) = bodies%v(:, i) - v_start(:, k)
      self%dw(:, i) = bodies%w(:, i) - w_start(:, k)
      call flight%release(i)
      call flight%set_load(i, [0.0_dp, 0.0_dp, 0.0_dp])
      if (any(dv /= 0.0_dp)) self%stats%loaded = self%stats%loaded + 1
    end do
  end subroutine resting_solve

  !> After a group's solve (groups small enough for the exact projection; not yet the
  !> frictionless ones of up to exact_limit contacts, which keep their one projection): the contacts
  !> that the bodies' turning, at the velocities found, brings lower by the step's end than
  !> the pass allowed (the pass could take the turning term only from the velocities before
  !> the solve) are projected again exactly (e = 0, normal impulses added to the solve's).
  !> Without this such a contact reaches the settling floor within the step: an impact that
  !> cuts the island and steps it again (at an automatic min_separation most of a pour's
  !> impacts; docs/benchmarks.md, "The turning term of the contact pass").
  !> Each projection turns the bodies anew, so the turning term is taken again from the
  !> velocities it gave, each allowance only ever tightened, up to max_rounds projections;
  !> a contact counts as late when it would end more than turning_slack below its aim.
  !> Left to the events: groups larger than projection_limit (tried: projecting the late
  !> contacts' neighbourhoods with the rest held, which oscillated; docs/attempts) and bodies
  !> turning more than max_turn in the step (a landing spinner: a second-order term is no
  !> model of it, and pushing it off made the 1 mm pours slower).
  subroutine repair_turning(self, bodies, contacts, members, impulse, h, err)
    class(resting_contact_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(inout) :: contacts(:)
    integer, intent(in) :: members(:)
    real(dp), intent(inout) :: impulse(:, :)   !< the group's impulses [N s], by members
    real(dp), intent(in) :: h
    type(error_t), intent(inout) :: err
    integer, parameter :: max_rounds = 8
    real(dp), parameter :: max_turn = 0.05_dp   ! [rad]
    real(dp), allocatable :: allowed(:), extra(:)
    logical, allocatable :: late(:)
    type(contact_t), allocatable :: group(:)
    integer :: k, m, round
    m = size(members)
    if (m > self%projection_limit .or. .not. any(contacts(members)%turning)) return
    allocate (allowed(m), late(m), extra(m))
    allowed = contacts(members)%allowed_approach
    do round = 1, max_rounds + 1
      do k = 1, m
        associate (con => contacts(members(k)))
          if (con%turning) allowed(k) = min(allowed(k), con%allowed_straight - &
                                            0.5_dp*h*max(-normal_curvature(bodies, con), 0.0_dp))
          late(k) = (normal_velocity(bodies, con) + allowed(k))*h < -self%turning_slack .and. &
                    max(norm2(bodies%w(:, con%a)), norm2(bodies%w(:, con%b)))*h <= max_turn
        end associate
      end do
      if (.not. any(late)) return
      if (round == 1) self%stats%turning_repairs = self%stats%turning_repairs + 1
      if (round > max_rounds) then
        self%stats%turning_left = self%stats%turning_left + 1
        return
      end if
      self%stats%turning_rounds = self%stats%turning_rounds + 1
      group = contacts(members)
      group%restitution = 0.0_dp
      group%allowed_approach = allowed
      call resolve_impacts(bodies, group, self%velocity_tolerance, 1, self%exact, err, extra)
      if (err%failed()) return
      do k = 1, m
        impulse(:, k) = impulse(:, k) + extra(k)*group(k)%normal
      end do
    end do
  end subroutine repair_turning

  !> The bodies were renumbered (a migration): body i is now new_index(i), 0 if it left, of
  !> n bodies. The velocity changes of the last pass follow the bodies that stayed (an
  !> island's step cut later takes its unused part back from them); the warm starts are
  !> keyed by global ids and need nothing.
  subroutine resting_remap_bodies(self, new_index, n)
    class(resting_contact_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n
    real(dp), allocatable :: dv(:, :), dw(:, :)
    integer :: i, ni
    if (allocated(self%dv)) then
      allocate (dv(3, n), dw(3, n))
      dv = 0.0_dp
      dw = 0.0_dp
      do i = 1, min(size(new_index), size(self%dv, 2))
        ni = new_index(i)
        if (ni == 0) cycle
        dv(:, ni) = self%dv(:, i)
        dw(:, ni) = self%dw(:, i)
      end do
      call move_alloc(dv, self%dv)
      call move_alloc(dw, self%dw)
    end if
    ! (false between calls: only its size matters)
    if (allocated(self%involved)) deallocate (self%involved)
    call ensure_involved(self, n)
  end subroutine resting_remap_bodies

  !> The per-body flag array of resting_solve, all false between calls (set and cleared for
  !> the bodies of each pass only).
  subroutine ensure_involved(self, n)
    type(resting_contact_t), intent(inout) :: self
    integer, intent(in) :: n
    logical, allocatable :: grown(:)
    if (.not. allocated(self%involved)) then
      allocate (self%involved(n))
      self%involved = .false.
    else if (size(self%involved) < n) then
      allocate (grown(n))
      grown = .false.
      call move_alloc(grown, self%involved)
    end if
  end subroutine ensure_involved

  !> Staggered projections (Kaufman, Sueda, James and Pai, ACM TOG 27(5), 2008) for a group
  !> with friction of moderate size: alternately the exact normal solve with the friction
  !> impulses held fixed (the inelastic projection of impulse_solver, from v* plus friction)
  !> and the friction solve with the normal impulses held fixed (projected Gauss-Seidel on
  !> the tangential impulses, each in its Coulomb disc), until the velocities stop changing.
  !> Normal impulses come out exact each round, so a stack carries its weight from the first
  !> round (plain Gauss-Seidel needs of the order of N^2 sweeps for N levels), and friction
  !> settles in a few rounds. impulse: warm start in, the impulses (world) out.
  subroutine staggered_solve(self, bodies, contacts, impulse, err)
    type(resting_contact_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(inout) :: contacts(:)
    real(dp), intent(inout) :: impulse(:, :)
    type(error_t), intent(inout) :: err
    !> Round cap. The rounds converge linearly, about 0.78 per round in a pile, so taking a
    !> friction error of 1e-2 m/s down to the round tolerance needs about 40 of them. With a
    !> cap of 20 (0.78^20 = 7e-3 left), a tower of 8 cubes in the 8-cube pour kept twisting
    !> at 5e-3 rad/s and never slept; with 60 it slept, for 3,237 events instead of 5,784
    !> and about 1.2x the wall time. Converged groups stop early, so only hard ones pay.
    integer, parameter :: max_rounds = 60
    !> PGS sweeps of the friction solve per round. With 20, a pile of 8 cubes leaning on its
    !> walls crept at mm/s for good; with 60 it came to rest and slept (1.8 s, and 4.0 s on
    !> another trajectory), for about 1.5x the cost per step (docs/contact.md, limits).
    integer, parameter :: friction_sweeps = 60
    !> Rounds end when no velocity changes by more than this [m/s]. The rounds converge
    !> linearly (about 0.78 per round in a pile), so 1e-9 (the PGS tolerance) took 20 rounds
    !> and more; 1e-6 takes about 10, and what it leaves is 3 orders below the sleep speed
    !> (an approaching residual is finished by the exact projection). The 8-cube pile then
    !> lands in 5,200 events instead of 9,900 and sleeps at 2.4 s instead of 4.0 s.
    real(dp), parameter :: round_tolerance = 1.0e-6_dp
    !> The friction solve of a round stops when a sweep changes no velocity by more than this
    !> fraction of the last round's change (and never looser than needed: self%tolerance at
    !> least). Early rounds move the normal impulses by far more than a tight friction solve
    !> would settle, so solving friction to 1e-9 m/s there is wasted (inexact inner solves of
    !> an outer fixed-point iteration); as the rounds converge the friction solves tighten
    !> with them, to 1e-8 m/s and below by the last rounds.
    real(dp), parameter :: inner_fraction = 1.0e-2_dp
    real(dp), allocatable :: v_star(:, :), w_star(:, :), v_round(:, :), lam_n(:), tangential(:, :)
    integer, allocatable :: members(:), side(:, :)
    type(pgs_setup_t) :: setup
    type(projection_warm_t) :: warm
    real(dp) :: change, friction_tolerance
    integer :: m, k, round, n_members
    m = size(contacts)
    contacts%restitution = 0.0_dp
    change = huge(1.0_dp)
    ! Only the group's moving bodies change: their velocities are kept, not the scene's.
    call group_members(bodies, contacts, members, n_members, side)
    allocate (v_star(3, n_members), w_star(3, n_members), v_round(3, n_members))
    do k = 1, n_members
      v_star(:, k) = bodies%v(:, members(k))
      w_star(:, k) = bodies%w(:, members(k))
    end do
    allocate (lam_n(m), tangential(3, m))
    do k = 1, m
      lam_n(k) = max(dot_product(impulse(:, k), contacts(k)%normal), 0.0_dp)
      tangential(:, k) = impulse(:, k) - dot_product(impulse(:, k), contacts(k)%normal)*contacts(k)%normal
    end do
    ! The poses do not change over the rounds: the friction solves share one setup.
    do round = 1, max_rounds
      do k = 1, n_members
        v_round(:, k) = bodies%v(:, members(k))
        bodies%v(:, members(k)) = v_star(:, k)
        bodies%w(:, members(k)) = w_star(:, k)
      end do
      ! friction held: apply it (clamped to the cones of the last normal impulses)
      call solve_contacts_pgs(bodies, contacts, tangential, self%tolerance, 0, self%pgs, fixed_normal=lam_n, &
                              setup=setup)
      ! exact normal impulses for it
      ! (E is the same every round: each projection starts from the last one's QR)
      call resolve_impacts(bodies, contacts, self%velocity_tolerance, 1, self%exact, err, lam_n, warm=warm)
      if (err%failed()) return
      ! friction for those normal impulses, to a tolerance that follows the rounds
      friction_tolerance = max(self%tolerance, inner_fraction*change)
      call solve_contacts_pgs(bodies, contacts, tangential, friction_tolerance, friction_sweeps, self%pgs, &
                              fixed_normal=lam_n, warm_applied=.true., setup=setup)
      change = 0.0_dp
      do k = 1, n_members
        change = max(change, maxval(abs(bodies%v(:, members(k)) - v_round(:, k))))
      end do
      if (round > 1 .and. change <= round_tolerance) exit
    end do
    do k = 1, m
      tangential(:, k) = tangential(:, k) - dot_product(tangential(:, k), contacts(k)%normal)*contacts(k)%normal
      impulse(:, k) = lam_n(k)*contacts(k)%normal + tangential(:, k)
    end do
    self%stats%staggered_rounds = self%stats%staggered_rounds + min(round, max_rounds)
    self%stats%staggered_solves = self%stats%staggered_solves + 1
    if (round > max_rounds) self%stats%staggered_capped = self%stats%staggered_capped + 1
  end subroutine staggered_solve

  !> Static friction, exactly. The iterative friction solves converge linearly, and what
  !> they leave lets a pile at rest creep at mm/s (a tower leaning on the walls of its box
  !> slid 7 mm in 2.7 s and never slept). When every loaded contact of a group already moves
  !> slower than stick_speed, the group is solved once more with every loaded contact held
  !> still: the impulses of those contacts are sought as non-negative combinations of the
  !> edges of a pyramid inscribed in each Coulomb cone (n + mu (cos a t1 + sin a t2), eight
  !> angles a), and non-negative least squares (Lawson-Hanson) chooses them so that the
  !> group's velocities, from what they would be without these impulses (vt_base), come as
  !> close to rest as they can in the mass norm: min |vt_base + E beta|. If they leave every
  !> loaded contact still (to the velocity tolerance) and no other contact of the group
  !> approaching, they are a solution of the same Coulomb problem, the one in which
  !> everything sticks, and replace the iterative one; otherwise nothing changes (a contact
  !> that must slide, or one that needs more than the pyramid's 92% of mu lambda_n).
  subroutine try_sticking(self, bodies, contacts, impulse, hold, err, stuck)
    type(resting_contact_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    real(dp), intent(inout) :: impulse(:, :)   !< the group's impulses applied so far (world) [N s]
    logical, intent(in) :: hold(:)             !< the contacts to hold still
    type(error_t), intent(inout) :: err
    logical, intent(out) :: stuck              !< held: velocities and impulses replaced
    integer, parameter :: edges = 8
    real(dp), allocatable :: e_matrix(:, :), vt(:), vt_base(:), beta(:), generator(:, :, :), vt_saved(:)
    integer, allocatable :: side(:, :), members(:), active(:)
    real(dp) :: t1(3), t2(3), u(3), angle, row(6)
    integer :: m, c, k, g, n_members, n_active, col, iterations
    logical :: converged
    stuck = .false.
    m = size(contacts)
    active = pack([(c, c=1, m)], hold)
    n_active = size(active)
    if (n_active == 0) return
    call group_members(bodies, contacts, members, n_members, side)
    ! Columns: the pyramid edges of every loaded contact, as mass-scaled velocity changes.
    allocate (e_matrix(6*n_members, edges*n_active), vt(6*n_members), generator(3, edges, n_active))
    e_matrix = 0.0_dp
    do k = 1, n_members
      vt(6*k - 5:6*k) = scaled_velocity(bodies, members(k))
    end do
    vt_base = vt
    do k = 1, n_active
      associate (con => contacts(active(k)), sa => side(1, active(k)), sb => side(2, active(k)))
        call tangent_basis(con%normal, t1, t2)
        do g = 1, edges
          angle = 2.0_dp*acos(-1.0_dp)*real(g - 1, dp)/real(edges, dp)
          generator(:, g, k) = con%normal + con%friction*(cos(angle)*t1 + sin(angle)*t2)
          col = edges*(k - 1) + g
          if (sb > 0) e_matrix(6*sb - 5:6*sb, col) = scaled_row(bodies, con%b, con%point, generator(:, g, k))
          if (sa > 0) e_matrix(6*sa - 5:6*sa, col) = &
            e_matrix(6*sa - 5:6*sa, col) - scaled_row(bodies, con%a, con%point, generator(:, g, k))
        end do
        ! the velocities without this contact's impulse so far
        if (sb > 0) then
          row = scaled_impulse(con%b, impulse(:, active(k)))
          vt_base(6*sb - 5:6*sb) = vt_base(6*sb - 5:6*sb) - row
        end if
        if (sa > 0) then
          row = scaled_impulse(con%a, impulse(:, active(k)))
          vt_base(6*sa - 5:6*sa) = vt_base(6*sa - 5:6*sa) + row
        end if
      end associate
    end do
    allocate (beta(edges*n_active))
    ! (only E beta matters: the pyramid's edges are dependent by construction, no spreading)
    call solve_nnls(e_matrix, -vt_base, beta, iterations, err, converged, spread=.false.)
    if (err%failed() .or. .not. converged) return
    vt_saved = vt
    vt = vt_base + matmul(e_matrix, beta)
    do k = 1, n_members
      call set_scaled_velocity(bodies, members(k), vt(6*k - 5:6*k))
    end do
    ! Every held contact still, no other one approaching: else back to the iterative answer.
    do c = 1, m
      if (hold(c)) then
        u = relative_velocity(bodies, contacts(c))
        if (norm2(u) <= 10.0_dp*self%velocity_tolerance) cycle
      else if (normal_velocity(bodies, contacts(c)) >= -contacts(c)%allowed_approach - self%velocity_tolerance) then
        cycle
      end if
      do k = 1, n_members
        call set_scaled_velocity(bodies, members(k), vt_saved(6*k - 5:6*k))
      end do
      return
    end do
    do k = 1, n_active
      impulse(:, active(k)) = matmul(generator(:, :, k), beta(edges*(k - 1) + 1:edges*k))
    end do
    stuck = .true.
    self%stats%stuck = self%stats%stuck + 1
  contains
    !> The mass-scaled velocity change of body i from impulse p at contact c's point (world).
    function scaled_impulse(i, p) result(dvt)
      integer, intent(in) :: i
      real(dp), intent(in) :: p(3)
      real(dp) :: dvt(6), size_p
      dvt = 0.0_dp
      size_p = norm2(p)
      if (size_p <= 0.0_dp) return
      dvt = size_p*scaled_row(bodies, i, contacts(active(k))%point, p/size_p)
    end function scaled_impulse
  end subroutine try_sticking

  !> Velocity of b minus velocity of a at contact c's point [m/s].
  pure function relative_velocity(bodies, c) result(u)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: c
    real(dp) :: u(3)
    u = bodies%v(:, c%b) + cross(bodies%w(:, c%b), c%point - bodies%x(:, c%b)) &
        - bodies%v(:, c%a) - cross(bodies%w(:, c%a), c%point - bodies%x(:, c%a))
  end function relative_velocity

  !> Number of distinct moving bodies touched by contacts.
  integer function moving_bodies(bodies, contacts) result(count_moving)
    type(bodies_t), intent(in) :: bodies
    type(contact_t), intent(in) :: contacts(:)
    integer, allocatable :: members(:), side(:, :)
    call group_members(bodies, contacts, members, count_moving, side)
  end function moving_bodies

end module resting_contact
