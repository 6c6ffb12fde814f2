!> The collision stage of a step: candidate pairs, distance correction, the contact pass,
!> time of contact of every candidate pair by conservative advancement, and, once the bodies
!> have been moved to the earliest contact, the contact sets of the touching pairs and their
!> simultaneous impulses (docs/contact.md, "One step").
!>
!> Per step: (1) limit_step caps the step so that no body moves more than one grid box;
!> (2) prepare puts every body's bounding sphere, grown by how far it can travel in the step
!> and by the contact band, into the bucket grid, takes the candidate pairs (two rings) and
!> the closest points of those that can come within the band, once for the step;
!> (3) correct_distances opens pairs that settled below 3/4 of the minimum separation;
!> (4) contact_pass solves the band contacts and the speculative ones (inelastic pairs that
!> can touch within the step) at velocity level (resting_contact); (5) earliest_contact
!> advances each pair (time_of_contact) with the motion the propagator will make, pairs the
!> pass solved down to the settling floor; the smallest time is the step; (6) after the
!> move, resolve builds the contact points of the pairs that reached contact (all features
!> within the contact tolerance) and applies the impulses (impulse_solver). Bodies far from
!> everything cost a grid entry and no closest-point query.
!>
!> This module holds the stage's type (its pair table, work arrays and statistics), the
!> interfaces of its procedures and the helpers shared with other modules; each job is a
!> submodule in its own file, so that one job reads (and recompiles) without the others:
!>   collision_stage_pairs (init, limit_step, prepare, reserve_table: steps 1-2);
!>   collision_stage_correction (correct_distances: step 3);
!>   collision_stage_pass (contact_pass, return_unused_pass: step 4);
!>   collision_stage_advance (earliest_contact, advance_candidate: step 5);
!>   collision_stage_impacts (resolve, settle, wake_all, drop_events: step 6).
module collision_stage
  use kinds, only: dp, i8
  use error_status, only: error_t
  use input_config, only: contact_config_t, run_config_t, integrator_config_t
  use shape, only: shape_library_t, SHAPE_SPHERE
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use bucket_grid, only: bucket_grid_t
  use advancement_bound, only: angular_speed_bound
  use time_of_contact, only: advancement_result_t
  use contact_features, only: contact_feature_t
  use impulse_solver, only: contact_t, impulse_stats_t
  use contact_solver, only: pgs_stats_t
  use resting_contact, only: resting_contact_t
  use contact_material, only: material_table_t
  use quaternion, only: quat_rotate_inverse
  use sleeping, only: sleep_t
  use gap_memo, only: gap_memo_t
  implicit none
  private
  public :: collision_stage_t, collision_stats_t, smallest_moving_extent, turning_reach, min_separation_for

  type :: collision_stats_t
    integer(i8) :: events = 0                  !< steps that ended at a contact
    integer(i8) :: advancement_iterations = 0  !< closest-point queries inside time of contact
    integer(i8) :: pair_tests = 0              !< candidate pairs given a closest-point query
    integer(i8) :: contacts = 0                !< contact points handed to the impulse solver
    integer(i8) :: capped = 0                  !< pairs stopped by the iteration cap (safe, short)
    integer(i8) :: corrections = 0             !< distance corrections (pairs pushed apart)
    integer(i8) :: corrections_capped = 0      !< corrections cut to half the band per body
    integer(i8) :: plane_skips = 0             !< pairs advanced from a second-order safe time (plane_bound)
    integer(i8) :: convex_bounds = 0           !< queries replaced by GJK's bound (convex_distance): iterates, certificates
    real(dp) :: min_separation = huge(1.0_dp)  !< smallest gap ever computed [m]
  end type collision_stats_t

  type :: collision_stage_t
    real(dp) :: target = 0.0_dp              !< min_separation [m]
    real(dp) :: tolerance = 0.0_dp           !< time-of-contact gap tolerance [m]
    real(dp) :: contact_tolerance = 0.0_dp   !< features within gap + this are contacts [m]
    real(dp) :: velocity_tolerance = 0.0_dp  !< approach speeds below this do not reflect [m/s]
    !> A pair in the contact band whose contact points approach slower than this settles
    !> towards the floor (bounded by conservative advancement) instead of stopping the step
    !> at once: contact solvers leave residuals of this order in large groups [m/s].
    real(dp) :: settle_speed = 0.0_dp
    real(dp) :: rest_speed = 0.0_dp          !< impacts slower than this are inelastic [m/s]
    logical :: turning_term = .true.         !< the pass allows for turning (contact_config_t)
    integer :: max_iterations = 100
    integer :: max_rounds = 100
    real(dp) :: box_size = 0.0_dp            !< grid box edge [m]
    type(bucket_grid_t) :: grid
    integer, allocatable :: pairs(:, :)
    integer :: n_pairs = 0
    integer, allocatable :: event_pairs(:, :) !< pairs that reached contact at the step's end
    integer :: n_events = 0
    integer :: zero_steps = 0                !< consecutive steps of length 0 (stall guard)
    integer(i8) :: stalled_pair(2) = 0       !< global ids of the last pair that stopped a step at once
    real(dp) :: pass_step = 0.0_dp           !< the step the last contact pass gave gravity for [s]
    type(collision_stats_t) :: stats
    type(impulse_stats_t) :: impulses
    type(pgs_stats_t) :: impact_friction      !< friction solves at impacts
    type(pgs_stats_t) :: residual_pgs         !< safety-net solves after unconverged projections
    type(resting_contact_t) :: resting        !< the contact pass of every step
    type(material_table_t) :: materials       !< restitution and friction per &body group
    type(sleep_t) :: sleep                    !< islands at rest held still until touched
    type(gap_memo_t) :: memo                  !< each pair's last closest-point query (gap_memo)
    integer, allocatable :: band_pairs(:, :)  !< pairs with contact points in the band at the last pass
    integer :: n_band_pairs = 0
    ! The step's candidate pairs (prepare): from the grid with every body's travel over the
    ! step as its margin, with their gaps at the step's start, shared by the contact pass and
    ! the time of contact (the pass changes velocities, not positions).
    real(dp), allocatable :: pair_gap0(:)     !< gap at the step's start (a lower bound where far) [m]
    real(dp), allocatable :: pair_normal(:, :) !< normal there, from the first body to the second
    logical, allocatable :: pair_far(:)       !< cannot come within the contact band in the step
    logical, allocatable :: pair_in_pass(:)   !< the contact pass solved contacts of this pair
    real(dp), allocatable :: grid_margin(:)   !< travel bound each body was entered with [m]
    real(dp), allocatable :: turn(:)          !< how far turning moves any surface point in the step [m]
    integer, allocatable :: contact_pair(:)   !< the pass: candidate pair of each contact point
    logical, allocatable :: held(:)           !< the pass: bodies it holds (false between passes)
    !> Event log (&output event_log): per body changed by an impact, time [s], global id,
    !> linear impulse [N s] and angular impulse about its centre of mass [N m s].
    logical :: log_events = .false.
    real(dp), allocatable :: log_rows(:, :)
    integer :: n_log = 0
    integer, allocatable :: slot_of(:)        !< local numbering of a correction's bodies (0 between calls)
    type(contact_t), allocatable :: contacts(:)
    integer(i8), allocatable :: keys(:, :)
    type(contact_feature_t), allocatable :: features(:)
  contains
    procedure :: init => stage_init
    procedure :: prepare => stage_prepare
    procedure :: correct_distances => stage_correct_distances
    procedure :: contact_pass => stage_contact_pass
    procedure :: return_unused_pass => stage_return_unused_pass
    procedure :: limit_step => stage_limit_step
    procedure :: earliest_contact => stage_earliest_contact
    procedure :: advance_candidate => stage_advance_candidate
    procedure :: resolve => stage_resolve
    procedure :: settle => stage_settle
    procedure :: drop_events => stage_drop_events
    procedure :: wake_all => stage_wake_all
    procedure :: reserve_table => stage_reserve_table
    procedure :: remap_bodies => stage_remap_bodies
  end type collision_stage_t

  ! The jobs' procedures (docs/contact.md, "One step"), each in its submodule's file.
  interface
    ! collision_stage_pairs.f90
    !> Tolerances from the deck's &contact and &run (auto values relative to the smallest
    !> body), the pair materials (built by the caller from the &body groups) and the grid box
    !> size from the smallest moving body. source: the deck, named in messages.
    !> smallest_extent: smallest_moving_extent over every rank [m] (default: this rank's).
    module subroutine stage_init(self, contact, run, materials, source, shapes, bodies, err, smallest_extent)
      class(collision_stage_t), intent(inout) :: self
      type(contact_config_t), intent(in) :: contact
      type(run_config_t), intent(in) :: run
      type(material_table_t), intent(in) :: materials
      character(len=*), intent(in) :: source
      type(shape_library_t), intent(in) :: shapes
      type(bodies_t), intent(in) :: bodies
      type(error_t), intent(inout) :: err
      real(dp), intent(in), optional :: smallest_extent
    end subroutine stage_init

    !> The largest step that keeps every body within one grid box.
    module pure real(dp) function stage_limit_step(self, bodies, flight, gravity, h, members) result(limited)
      class(collision_stage_t), intent(in) :: self
      type(bodies_t), intent(in) :: bodies
      type(free_flight_t), intent(in) :: flight
      real(dp), intent(in) :: gravity(3), h
      integer, intent(in), optional :: members(:)
    end function stage_limit_step

    !> The step's candidate pairs, with their gaps and normals at the step's start.
    module subroutine stage_prepare(self, bodies, shapes, flight, h, gravity, err, margins)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(in) :: bodies
      type(shape_library_t), intent(in) :: shapes
      type(free_flight_t), intent(in) :: flight
      real(dp), intent(in) :: h, gravity(3)
      type(error_t), intent(inout) :: err
      real(dp), intent(in), optional :: margins(:)
    end subroutine stage_prepare

    !> Room in the step's pair table for m pairs of n bodies.
    module subroutine stage_reserve_table(self, m, n)
      class(collision_stage_t), intent(inout) :: self
      integer, intent(in) :: m, n
    end subroutine stage_reserve_table

    !> The bodies were renumbered (a migration): body i is now new_index(i), 0 if it left,
    !> of n. What the stage keeps per body between steps (sleeping, the last pass's velocity
    !> changes) follows the bodies that stayed; the step's per-body work arrays are sized for n.
    module subroutine stage_remap_bodies(self, new_index, n)
      class(collision_stage_t), intent(inout) :: self
      integer, intent(in) :: new_index(:)
      integer, intent(in) :: n
    end subroutine stage_remap_bodies

    ! collision_stage_correction.f90
    !> Opens the candidate pairs settled below 3/4 of the minimum separation.
    module subroutine stage_correct_distances(self, bodies, shapes, flight)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(inout) :: bodies
      type(shape_library_t), intent(in) :: shapes
      type(free_flight_t), intent(inout) :: flight
    end subroutine stage_correct_distances

    ! collision_stage_pass.f90
    !> The contact pass at the start of a step of h over the step's candidate pairs.
    module subroutine stage_contact_pass(self, bodies, shapes, flight, h, gravity, err, members)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(inout) :: bodies
      type(shape_library_t), intent(in) :: shapes
      type(free_flight_t), intent(inout) :: flight
      real(dp), intent(in) :: h, gravity(3)
      type(error_t), intent(inout) :: err
      integer, intent(in), optional :: members(:)
    end subroutine stage_contact_pass

    !> Takes back the pass's velocity change for the part of the step not taken.
    module subroutine stage_return_unused_pass(self, bodies, flight, h_taken, members, pass_step)
      class(collision_stage_t), intent(in) :: self
      type(bodies_t), intent(inout) :: bodies
      type(free_flight_t), intent(inout) :: flight
      real(dp), intent(in) :: h_taken   !< the step taken [s]
      integer, intent(in), optional :: members(:)
      real(dp), intent(in), optional :: pass_step
    end subroutine stage_return_unused_pass

    ! collision_stage_advance.f90
    !> Earliest time of contact in [0, h] over all candidate pairs; keeps the pairs in contact then.
    module subroutine stage_earliest_contact(self, bodies, shapes, flight, time_now, h, gravity, config, h_event, err)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(inout), target :: bodies
      type(shape_library_t), intent(in), target :: shapes
      type(free_flight_t), intent(inout), target :: flight
      real(dp), intent(in) :: time_now, h, gravity(3)
      type(integrator_config_t), intent(in) :: config
      real(dp), intent(out) :: h_event
      type(error_t), intent(inout) :: err
    end subroutine stage_earliest_contact

    !> Time of contact of candidate pair k over [0, step] from time_now.
    module subroutine stage_advance_candidate(self, bodies, shapes, flight, gravity, config, time_now, k, step, &
                                              max_iterations, res)
      class(collision_stage_t), intent(inout), target :: self
      type(bodies_t), intent(inout), target :: bodies
      type(shape_library_t), intent(in), target :: shapes
      type(free_flight_t), intent(inout), target :: flight
      real(dp), intent(in) :: gravity(3), time_now
      type(integrator_config_t), intent(in) :: config
      integer, intent(in) :: k
      real(dp), intent(in) :: step          !< [s] from time_now
      integer, intent(in) :: max_iterations
      type(advancement_result_t), intent(out) :: res
    end subroutine stage_advance_candidate

    ! collision_stage_impacts.f90
    !> After the move to the event: contact points and simultaneous impulses of the pairs in contact.
    module subroutine stage_resolve(self, bodies, shapes, flight, h_event, h_planned, err, time)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(inout) :: bodies
      type(shape_library_t), intent(in) :: shapes
      type(free_flight_t), intent(inout) :: flight
      real(dp), intent(in) :: h_event     !< the step taken [s]
      real(dp), intent(in) :: h_planned   !< the step before the contact cut it [s]
      type(error_t), intent(inout) :: err
      real(dp), intent(in), optional :: time
    end subroutine stage_resolve

    !> After a step of h [s]: islands quiet for long enough fall asleep.
    module subroutine stage_settle(self, bodies, shapes, flight, h)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(inout) :: bodies
      type(shape_library_t), intent(in) :: shapes
      type(free_flight_t), intent(inout) :: flight
      real(dp), intent(in) :: h
    end subroutine stage_settle

    !> No pair of this rank is in contact at the step's end.
    module subroutine stage_drop_events(self)
      class(collision_stage_t), intent(inout) :: self
    end subroutine stage_drop_events

    !> Every sleeping body wakes.
    module subroutine stage_wake_all(self, bodies, flight)
      class(collision_stage_t), intent(inout) :: self
      type(bodies_t), intent(inout) :: bodies
      type(free_flight_t), intent(inout) :: flight
    end subroutine stage_wake_all
  end interface

contains

  !> The largest extent (bounding-sphere diameter) of the smallest moving body this rank
  !> owns [m], huge() if it owns none. The grid box and the auto minimum separation follow the
  !> smallest over all ranks (the driver reduces it), so every rank uses the same ones.
  pure real(dp) function smallest_moving_extent(shapes, bodies) result(smallest)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer :: i
    smallest = huge(1.0_dp)
    do i = 1, bodies%n_owned
      if (.not. bodies%fixed(i)) smallest = min(smallest, 2.0_dp*shapes%shapes(bodies%shape_id(i))%bounding_radius)
    end do
  end function smallest_moving_extent

  !> The minimum separation of a run [m]: the deck's, or auto, 1e-4 of smallest (the
  !> smallest moving body's extent over every rank [m]; huge() when nothing moves).
  pure real(dp) function min_separation_for(contact, smallest) result(target)
    type(contact_config_t), intent(in) :: contact
    real(dp), intent(in) :: smallest
    target = contact%min_separation
    if (target <= 0.0_dp) then
      if (smallest >= huge(1.0_dp)) then
        target = 1.0e-4_dp   ! nothing moves: the box of 1 m below
      else
        target = 1.0e-4_dp*smallest   ! auto: docs/input.md
      end if
    end if
  end function min_separation_for

  !> The fastest any surface point of body k moves relative to its centre of mass by turning,
  !> Omega R [m/s] (zero for analytic spheres: turning moves none of their surface).
  pure real(dp) function turning_reach(shapes, bodies, k)
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: k
    if (bodies%fixed(k) .or. shapes%shapes(bodies%shape_id(k))%kind == SHAPE_SPHERE) then
      turning_reach = 0.0_dp
    else
      ! 1e-12 relative slack: the propagators conserve T to round-off, not exactly.
      turning_reach = (1.0_dp + 1.0e-12_dp)*angular_speed_bound(bodies%inertia(:, k), &
                      quat_rotate_inverse(bodies%q(:, k), bodies%w(:, k)))*shapes%shapes(bodies%shape_id(k))%bounding_radius
    end if
  end function turning_reach

end module collision_stage
