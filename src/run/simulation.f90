!> One run: builds shapes and bodies from a deck (or a checkpoint), owns the clock, and
!> drives the loop { choose the step -> advance the bodies -> history, frames, checkpoints }.
!> Each stage reads the state and writes only its own result; only this loop owns time.
!> The module holds the type, the set-up and the restart; each other job is a submodule in
!> its own file, its procedures declared (and documented) in the interface block below:
!>   simulation_windows (the domain decomposition: bricks, window rule, migration),
!>   simulation_steps (the loop of both event loops, outputs due, progress, stops),
!>   simulation_output (history rows, frames, checkpoints, the summary).
module simulation
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kinds, only: dp, i8
  use constants, only: name_length, line_length
  use error_status, only: error_t, ERR_INPUT, ERR_NUMERIC, ERR_CHECKPOINT, ERR_INTERNAL
  use string_utils, only: str, join_path
  use parallel_env, only: parallel_t
  use input_config, only: deck_t, body_spec_t, EVENTS_LOCAL, EVENTS_GLOBAL, ROTATION_EXACT
  use shape, only: shape_library_t
  use body_state, only: bodies_t, copy_row
  use body_builder, only: build_shapes, build_bodies, count_bodies, build_materials
  use contact_material, only: material_table_t
  use ownership, only: contact_possible
  use domain, only: domain_t, box_range_t, suggest_dims
  use migration, only: migrate_bodies, migration_stats_t
  use gid_blocks, only: gather_gid_blocks
  use restart_check, only: check_restored_state, check_same_bodies, compare_decks, deck_change_t
  use deck_reader, only: effective_deck_lines, share_block
  use conservation, only: system_totals_t, compute_totals
  use overlap_check, only: check_initial_overlaps
  use resolution_check, only: check_position_resolution
  use collision_stage, only: collision_stage_t, smallest_moving_extent, min_separation_for
  use event_loop, only: event_loop_t
  use newmark_integrator, only: free_flight_stats_t
  use free_flight, only: free_flight_t
  use history_writer, only: history_writer_t, history_record_t, history_fresh_start
  use frame_writer, only: frame_writer_t
  use checkpoint_meta, only: checkpoint_meta_t, bodies_checksum
  use checkpoint_io, only: write_checkpoint, read_checkpoint, check_checkpoint_matches
  use event_log_writer, only: write_event_log
  use stop_request, only: stop_signal_received, signal_name
  implicit none
  private

  !> The phases of a run's start-up timed on every rank (the summary prints the slowest
  !> rank's): what does not shrink with more ranks shows here.
  integer, parameter :: N_STARTUP_PHASES = 7
  character(len=14), parameter :: STARTUP_PHASE_NAMES(N_STARTUP_PHASES) = [character(len=14) :: &
    'deck', 'effective deck', 'bodies', 'checks', 'owners', 'first outputs', 'loop set-up']
  public :: simulation_t, choose_event_loop

  !> A step that would leave less than this fraction of dt_max before an output or
  !> checkpoint time is stretched to land on it: no sliver steps.
  real(dp), parameter :: sliver_fraction = 1.0e-6_dp
  !> Exit status of a run stopped by &run wall_limit: 75, EX_TEMPFAIL of sysexits.h ("try
  !> again": restart me), distinct from the error codes (1-7) and from 128 + a signal.
  integer, parameter, public :: exit_wall_limit = 75

  type :: simulation_t
    type(deck_t) :: deck
    type(shape_library_t) :: shapes
    type(bodies_t) :: bodies
    character(len=name_length), allocatable :: group_names(:)
    character(len=:), allocatable :: output_dir
    type(frame_writer_t) :: frames
    type(history_writer_t) :: history
    real(dp) :: time = 0.0_dp
    integer(i8) :: step = 0
    integer(i8) :: first_step = 0             !< step this run started from (restarts)
    integer(i8) :: n_total = 0
    real(dp) :: next_output = 0.0_dp
    real(dp) :: output_interval = 0.0_dp      !< [s] effective (auto resolved)
    real(dp) :: history_interval = 0.0_dp     !< [s] effective (auto resolved)
    real(dp) :: next_history = 0.0_dp
    real(dp) :: next_checkpoint = huge(1.0_dp)
    real(dp) :: wall_before = 0.0_dp      !< wall time of earlier runs (restarts) [s]
    real(dp) :: wall_start = 0.0_dp
    !> This rank's share of the effective deck's lines (deck_reader effective_deck_lines;
    !> share_deck_lines), made once at init: the deck does not change during a run and
    !> every checkpoint stores them, each rank its share (formatting them at each checkpoint
    !> was most of a 10^4-body gas's run; every rank holding all of them, 190 MB per rank
    !> at 100,000 bodies)
    character(len=:), allocatable :: deck_lines(:)
    real(dp) :: startup_wall = 0.0_dp     !< wall time of init on this rank, this run [s]
    !> the start-up's wall time on this rank by phase (STARTUP_PHASE_NAMES) [s]
    real(dp) :: startup_phases(N_STARTUP_PHASES) = 0.0_dp
    real(dp) :: last_progress = 0.0_dp
    real(dp) :: last_dt = 0.0_dp
    real(dp) :: integration_wall = 0.0_dp     !< wall time spent moving bodies, this run [s]
    real(dp) :: contact_pass_wall = 0.0_dp    !< wall time in the resting-contact pass, this run [s]
    real(dp) :: detection_wall = 0.0_dp       !< wall time in broad phase and time of contact [s]
    real(dp) :: resolve_wall = 0.0_dp         !< wall time in impacts and sleeping [s]
    type(system_totals_t) :: initial          !< totals at t = 0 (carried through restarts)
    real(dp) :: max_energy_error = 0.0_dp     !< largest relative energy error seen
    real(dp) :: max_momentum_error = 0.0_dp
    real(dp) :: max_angular_momentum_error = 0.0_dp
    type(free_flight_stats_t) :: flight
    type(free_flight_t) :: propagator         !< moves bodies between events
    type(collision_stage_t) :: collisions     !< times of contact and impulses
    type(event_loop_t) :: events              !< the local event loop (local = .true.)
    logical :: local = .false.                !< events = 'local': the local loop, not global steps
    !> Bodies owned by the brick of their centre (docs/architecture.md, "Domain
    !> decomposition"): several ranks and no interaction possible before t_end.
    logical :: decomposed = .false.
    !> Every owned body is in the brick of its centre, as take_brick left it, and no ghost is
    !> held: the first cross-rank window's start has nothing to migrate.
    logical :: in_own_bricks = .false.
    type(domain_t) :: dom
    real(dp) :: window_end = huge(1.0_dp)     !< the next migration [s]
    real(dp) :: previous_stop = 0.0_dp        !< the last output stop of the local loop [s]
    integer(i8) :: windows = 0                !< windows ended by a migration, this run
    !> Wall time in window ends on this rank, this run [s]: all of end_window (migration with
    !> its waits, evaluating arrivals, the local loop brought up to date), and of it the loop's
    !> part; the pair certificates computed there (the load report's window cost)
    real(dp) :: window_wall = 0.0_dp
    real(dp) :: window_loop_wall = 0.0_dp
    integer(i8) :: window_certificates = 0
    !> Window ends at which an island split between ranks made the local loop be built
    !> again (event_loop%remap_bodies), this rank
    integer(i8) :: window_rebuilds = 0
    type(migration_stats_t) :: migration
    !> Cross-rank windows (docs/architecture.md, "Cross-rank contacts"): a decomposed run
    !> whose bodies may meet across bricks (elastic, no gravity: no contact passes). Each
    !> window: migration, the halo of two rings as ghosts with their anchors, the fixed
    !> bodies as ghosts on every rank, the loop built over both, a run that stops where a
    !> ghost is needed; if some rank stopped, every rank runs again from the window's start
    !> to the earliest such time, and cross-rank impacts there are taken by the owner of the
    !> lower global id, the new anchors of ghosts sent to their owners.
    logical :: cross_windows = .false.
    type(bodies_t) :: statics                 !< every fixed body of the scene (ghosts on every rank)
    !> per owned row: the sides of its brick (bits as event_loop's zone_sides) within two boxes
    !> of which it was at the window's start: the neighbours there hold it as a ghost
    integer, allocatable :: zone(:)
    real(dp) :: cross_r_max = 0.0_dp          !< largest bounding radius of a moving body of the scene [m]
    real(dp) :: cross_skin = 0.0_dp           !< how far a body may leave its brick before it migrates [m]
    !> per ghost row: its owner's trajectory version when it came (-1: a fixed body)
    integer(i8), allocatable :: ghost_versions(:)
    !> windows, repeated (rolled back), cross phases, ghost updates sent, light starts,
    !> bodies sent at light starts to neighbours they came near (re-zoned)
    integer(i8) :: cross_count(6) = 0
    real(dp) :: cross_wall(2) = 0.0_dp        !< wall in window starts (migration, halo, loop built), in repeated runs [s]
    logical :: restarted = .false.
    !> Why the run stopped before t_end (run_stopped): 0 it did not, 128 + the signal number
    !> for SIGTERM/SIGINT (143, 130: what shells and schedulers report for a signal), or
    !> exit_wall_limit; stop_reason and stop_checkpoint say why and where it can go on from.
    integer :: stop_code = 0
    character(len=:), allocatable :: stop_reason, stop_checkpoint
  contains
    procedure :: init => simulation_init
    procedure :: run => simulation_run
    procedure :: summary => simulation_summary
    procedure :: free => simulation_free
    procedure, private :: record_history, write_frame, write_checkpoint_now, fill_meta, restart_from
  end type simulation_t

  interface
    ! simulation_windows.f90
    !> The bricks of this run on par's ranks (decomposed = .true.), or, when the scene is too
    !> small to give every rank two grid boxes along a split axis, none (a notice; every body
    !> then runs on rank 0). The global box holds every body's bounding sphere at the start.
    !> box: the grid box of the bricks [m] (default the collision grid's).
    module subroutine decompose(self, par, everyone, err, box)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(inout) :: par
      type(bodies_t), intent(in) :: everyone
      type(error_t), intent(inout) :: err
      real(dp), intent(in), optional :: box
    end subroutine decompose
    ! simulation_cross_windows.f90
    !> The run of cross_windows (local loop, several ranks, bodies that may meet across
    !> bricks): windows up to each output time, see simulation_t%cross_windows.
    module subroutine run_cross_windows(self, par, err)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine run_cross_windows
    !> The grid box of the bricks for cross_windows [m]: large enough that two rings of it
    !> hold every body that can reach an owned body while no body moves more than half a
    !> collision grid box past the skin s outside its brick (docs/architecture.md, "Why two
    !> rings are enough"): 2 R_max + band + h + s, R_max the largest bounding radius of a
    !> moving body, h the collision grid's box, s the &parallel skin (auto: h), and at least h.
    module real(dp) function cross_box_size(self, everyone) result(box)
      type(simulation_t), intent(inout) :: self   !< (keeps R_max and s: cross_r_max, cross_skin)
      type(bodies_t), intent(in) :: everyone
    end function cross_box_size
    !> The bodies of all whose centre lies in this rank's brick, in global-id order.
    module subroutine take_brick(all, dom, owned)
      type(bodies_t), intent(in) :: all
      type(domain_t), intent(in) :: dom
      type(bodies_t), intent(inout) :: owned
    end subroutine take_brick
    !> The length of the next window [s]: the longest time in which no body can reach a brick
    !> two bricks away from its owner's along any axis, so that at the window's end every body
    !> is in its owner's brick or a face, edge or corner neighbour's and migration needs only
    !> the neighbours. Along each axis a body has the room from its position to the far face
    !> of the neighbouring brick on either side (none beyond the rank grid: a body there stays
    !> in the edge brick), 0.9 of it for round-off; it covers at most |v_k| tau + |a_k| tau^2/2
    !> (velocity now, from the anchor, and gravity or its load). The global loop ends a window
    !> at the first step end past it, and a step moves a body at most one grid box more: one
    !> box less room. The smallest over every rank (collective).
    module real(dp) function motion_window(self, par) result(window)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
    end function motion_window
    !> A window's end: every body goes to the rank of its brick with its flight record (the
    !> anchor: trajectories go on bit for bit) and its trajectory version, then the local
    !> loop follows the bodies (event_loop%remap_bodies: certificates of pairs that stayed
    !> kept, arrivals certified; built again, keeping anchors, if an island was split).
    module subroutine end_window(self, par, err)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine end_window
    !> Every owned body to the rank of its brick (migrate_bodies), its flight record with it:
    !> only the bodies that leave carry theirs, the others' move to their new rows in place
    !> (free_flight remap) and the arrivals' are set from what came (packing every record,
    !> migrating, copying and unpacking them all was four copies of 36 MB at 50,000 bodies).
    !> versions: as migrate_bodies'; new_index: the row each row before became (0: gone).
    module subroutine migrate_owned(self, par, new_index, err, versions)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      integer, allocatable, intent(out) :: new_index(:)
      type(error_t), intent(inout) :: err
      integer(i8), allocatable, intent(inout), optional :: versions(:)
    end subroutine migrate_owned
    ! simulation_steps.f90
    module subroutine simulation_run(self, par, err)
      class(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine simulation_run
    !> The run with the local event loop: events processed up to each output, history,
    !> checkpoint or end time, where every body is evaluated and the outputs written; after a
    !> checkpoint the loop is built again from the state written, as a restart builds it.
    module subroutine run_local(self, par, err)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine run_local
    !> At a point every rank reaches, with every body at self%time: stops the run when some
    !> rank received SIGTERM or SIGINT or this run's wall time reached &run wall_limit (one
    !> collective for both), after writing checkpoint_signal.h5 or checkpoint_wall_limit.h5
    !> and the event log. Sets stop_code, stop_reason, stop_checkpoint; the driver says it.
    module subroutine stop_if_requested(self, par, err)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine stop_if_requested
    !> What is due at self%time, in both loops: a history row (at each history multiple,
    !> output time and the end), a frame (output times and the end), a checkpoint (its
    !> times before the end; checkpointed says one was written).
    module subroutine write_due_outputs(self, par, t_end, checkpointed, err)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      real(dp), intent(in) :: t_end
      logical, intent(out) :: checkpointed
      type(error_t), intent(inout) :: err
    end subroutine write_due_outputs
    !> The event log (&output event_log), one file per rank (events.csv on one rank).
    module subroutine write_events(self, par, err)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine write_events
    module subroutine progress(self, par)
      type(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
    end subroutine progress
    ! simulation_output.f90
    module subroutine record_history(self, par, err)
      class(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine record_history
    module subroutine write_frame(self, par, err)
      class(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      type(error_t), intent(inout) :: err
    end subroutine write_frame
    module subroutine write_checkpoint_now(self, par, name, err)
      class(simulation_t), intent(inout) :: self
      type(parallel_t), intent(in) :: par
      character(len=*), intent(in) :: name
      type(error_t), intent(inout) :: err
    end subroutine write_checkpoint_now
    !> What a checkpoint needs besides the bodies, and the deck fingerprint it is checked with.
    module subroutine fill_meta(self, par, meta)
      class(simulation_t), intent(in) :: self
      type(parallel_t), intent(in) :: par
      type(checkpoint_meta_t), intent(out) :: meta
    end subroutine fill_meta
    module subroutine simulation_summary(self, par)
      class(simulation_t), intent(in) :: self
      type(parallel_t), intent(in) :: par
    end subroutine simulation_summary
  end interface

contains

  subroutine simulation_init(self, par, deck_given, output_dir, restart_path, err, started_at)
    class(simulation_t), intent(inout) :: self
    type(parallel_t), intent(inout) :: par     !< (a decomposed run makes its Cartesian communicator)
    !> the run's deck; its &body specs move into the simulation (deck_given%bodies is not
    !> allocated on return): a copy was 141 MB of fresh pages on every rank for 100,000
    !> bodies (1,416 bytes a spec, most of them its mesh path)
    type(deck_t), intent(inout) :: deck_given
    character(len=*), intent(in) :: output_dir     !< where frames, history, checkpoints go
    character(len=*), intent(in) :: restart_path   !< checkpoint to continue from, or ''
    type(error_t), intent(inout) :: err
    !> par%wtime() when the run started, before its deck was read: the run's wall time and
    !> start-up count from there (default: now)
    real(dp), intent(in), optional :: started_at
    real(dp) :: phase_start
    integer, allocatable :: shape_of_group(:)
    type(bodies_t) :: everyone
    type(material_table_t) :: materials
    type(checkpoint_meta_t) :: meta
    integer(i8) :: first, last, pair(2)
    logical :: contacts, local, tried
    real(dp) :: h_brick
    character(len=:), allocatable :: why
    integer :: k
    type(body_spec_t), allocatable :: specs(:)

    call move_alloc(deck_given%bodies, specs)
    self%deck = deck_given
    call move_alloc(specs, self%deck%bodies)
    associate (deck => self%deck)
      phase_start = par%wtime()
      self%wall_start = phase_start
      if (present(started_at)) self%wall_start = started_at
      call next_phase(1)
      call share_deck_lines(self, par)
      call next_phase(2)
      self%last_progress = self%wall_start
      self%output_dir = output_dir
      allocate (self%group_names(deck%n_bodies))
      do k = 1, deck%n_bodies
        self%group_names(k) = deck%bodies(k)%name
      end do

      call build_shapes(deck, self%shapes, shape_of_group, err)
      if (err%failed()) return
      self%n_total = count_bodies(deck)
      ! Every rank builds every body (ids in deck order): the start-up checks, a restart's
      ! comparison and the choice of owners need them all. That is O(all bodies) per rank but
      ! cheap (0.03 s for 93,312 bodies); the costly parts, the overlap test's exact pair tests
      ! and contact_possible's sweep, are shared among the ranks (docs/architecture.md,
      ! "Domain decomposition in a run").
      call build_bodies(deck, self%shapes, shape_of_group, deck%run%gravity, 1_i8, self%n_total, everyone, err)
      if (err%failed()) return
      call next_phase(3)
      if (len_trim(restart_path) > 0) then
        ! Everything about the checkpoint is checked before any output is touched.
        call restore_checkpoint(self, par, restart_path, everyone, meta, err)
        if (err%failed()) return
      else
        call check_initial_overlaps(deck, self%shapes, everyone, err, par=par)
        if (err%failed()) return
      end if
      ! (at a restart too: the bodies may have gone far from the origin since the start)
      call check_position_resolution(deck, self%shapes, everyone, &
                                     min_separation_for(deck%contact, smallest_moving_extent(self%shapes, everyone)), &
                                     deck%contact%min_separation <= 0.0_dp, err)
      if (err%failed()) return
      call next_phase(4)
      ! One grid box size and one auto minimum separation for every rank: from the smallest
      ! moving body of all (every rank holds every body here); per-body tables are sized
      ! for all of them, so that migration never outgrows them.
      call build_materials(deck, materials)
      call self%collisions%init(deck%contact, deck%run, materials, deck%path, self%shapes, everyone, err)
      if (err%failed()) return
      ! Owners: the bricks of a domain decomposition when no two bodies can interact before
      ! t_end, otherwise every body on rank 0 (contacts across ranks are not built yet).
      contacts = .false.
      if (par%n_ranks > 1) then
        contacts = contact_possible(par, self%shapes, everyone, deck%run%t_end - self%time, deck%run%gravity, pair, &
                                    2.0_dp*(self%collisions%target + self%collisions%tolerance + &
                                            self%collisions%contact_tolerance))
        call choose_event_loop(deck, local, err)
        if (err%failed()) return
        tried = contacts .and. local .and. cross_contacts_built(deck, self%collisions)
        if (tried) then
          ! bodies of different bricks may meet: exact windows with ghosts (no contact passes)
          ! (the box first: cross_box_size keeps R_max and the skin in self)
          h_brick = cross_box_size(self, everyone)
          call decompose(self, par, everyone, err, h_brick)
          if (err%failed()) return
          self%cross_windows = self%decomposed
          if (self%decomposed) then
            contacts = .false.
            call take_statics(everyone, self%statics)
            if (par%is_root()) then
              write (*, '(a)') '  bodies of different bricks may meet (bodies '//str(pair(1))//' and '//str(pair(2))// &
                ' may touch): cross-rank windows with two rings of ghosts, migration skin '// &
                trim(adjustl(str(self%cross_skin, '(es10.3)')))//' m'
              flush (output_unit)
            end if
          end if
        end if
        if (contacts .and. par%is_root()) then
          if (tried) then
            why = 'the scene is too small for the bricks of cross-rank windows (above)'
          else
            why = 'contacts between bodies of different ranks are built only for scenes without contact '// &
                  'passes (no gravity, every restitution above 0, events = ''local'')'
          end if
          write (*, '(a)') 'ricochet: notice: bodies '//str(pair(1))//' and '//str(pair(2))//' may touch before '// &
            't_end, and '//why//': every body runs on rank 0, the other '//str(par%n_ranks - 1)//' rank(s) wait'
          flush (output_unit)
        end if
        if (.not. contacts .and. .not. self%decomposed) call decompose(self, par, everyone, err)
        if (err%failed()) return
      end if
      if (self%decomposed) then
        call take_brick(everyone, self%dom, self%bodies)
        self%in_own_bricks = .true.
      else
        ! every body on rank 0 (the only rank of a serial run)
        first = 1
        last = merge(self%n_total, 0_i8, par%is_root())
        call take_rows(everyone, first, last, self%bodies)
      end if
      call everyone%free()
      if (self%cross_windows) then
        ! (room for the first window's ghosts: a quarter of the owned rows, 12% for the
        ! 100,000-sphere gas on two ranks; more are taken by a reallocation)
        call self%propagator%init(self%bodies%n_owned, deck%integrator, &
                                  capacity=self%bodies%n_owned + self%bodies%n_owned/4)
      else
        call self%propagator%init(self%bodies%n_owned, deck%integrator)
      end if

      self%collisions%log_events = deck%output%event_log
      call choose_event_loop(deck, self%local, err)
      if (err%failed()) return
      if (deck%output%checkpoint_interval > 0.0_dp) then
        self%next_checkpoint = deck%output%checkpoint_interval
      end if
      ! Auto intervals (docs/input.md): 100 frames per run, 10 history rows per frame.
      self%output_interval = deck%output%interval
      if (self%output_interval <= 0.0_dp) self%output_interval = deck%run%t_end/100.0_dp
      self%history_interval = deck%output%history_interval
      if (self%history_interval <= 0.0_dp) self%history_interval = self%output_interval/10.0_dp
      self%next_output = 0.0_dp
      call next_phase(5)

      call self%frames%init(par, self%output_dir, err)
      if (err%failed()) return

      if (len_trim(restart_path) > 0) then
        call self%restart_from(meta, par%is_root())
      else
        call compute_totals(par, self%bodies, deck%run%gravity, self%initial)
      end if
      ! A fresh run starts a new history; a restart keeps the rows up to its time.
      call self%history%init(par, join_path(self%output_dir, 'history.csv'), &
                             merge(self%time, history_fresh_start, self%restarted), err)
      if (err%failed()) return
      ! History rows fall at the first step end at or after each multiple of the interval; the
      ! next one follows from the time alone, so a restart needs nothing more.
      self%next_history = (aint(self%time/self%history_interval) + 1.0_dp)*self%history_interval
      if (.not. self%restarted) then
        call self%record_history(par, err)
        if (err%failed()) return
        call self%write_frame(par, err)
        if (err%failed()) return
      end if
      call next_phase(6)
      if (self%local) call self%events%init(self%collisions, self%bodies, self%shapes, self%propagator, &
                                            deck%run%gravity, deck%integrator, self%time, deck%run%dt_max, &
                                            min(deck%run%t_end, self%next_checkpoint), err)
      self%previous_stop = self%time
      if (self%decomposed .and. .not. self%cross_windows) self%window_end = self%time + motion_window(self, par)
      call next_phase(7)
      self%startup_wall = par%wtime() - self%wall_start
    end associate
  contains
    !> Phase k ends now (the deck's from started_at to init's entry).
    subroutine next_phase(k)
      integer, intent(in) :: k
      real(dp) :: now
      now = par%wtime()
      if (k == 1) then
        self%startup_phases(1) = now - self%wall_start
      else
        self%startup_phases(k) = now - phase_start
      end if
      phase_start = now
    end subroutine next_phase
  end subroutine simulation_init

  !> This rank's share of the effective deck's lines (self%deck_lines): a block of the body
  !> groups (rank 0 the settings too), so that the shares in rank order are the lines one
  !> rank formats alone. Formatting 100,000 bodies' reals was most of a run's start-up, the
  !> same on every rank; every rank then received all the lines, which only a restart's
  !> comparison needs (restore_checkpoint gathers them).
  subroutine share_deck_lines(self, par)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    integer :: groups(2)
    if (par%n_ranks == 1) then
      call effective_deck_lines(self%deck, self%deck_lines)
      return
    end if
    ! (the block of groups this rank parsed too: shared_deck)
    call share_block(self%deck%n_bodies, [par%rank, par%n_ranks], groups(1), groups(2))
    call effective_deck_lines(self%deck, self%deck_lines, groups, settings=par%rank == 0)
  end subroutine share_deck_lines

  !> The event loop a deck asks for: local (default with exact rotation) or global steps.
  subroutine choose_event_loop(deck, local, err)
    type(deck_t), intent(in) :: deck
    logical, intent(out) :: local
    type(error_t), intent(inout) :: err
    select case (trim(deck%integrator%events))
    case (EVENTS_LOCAL)
      local = .true.
      if (deck%integrator%rotation /= ROTATION_EXACT) then
        call err%set(ERR_INPUT, deck%path//": &integrator: events = 'local' needs rotation = 'exact' (bodies are "// &
                     "evaluated from their anchors); use events = 'global' with rotation = 'newmark'")
      end if
    case (EVENTS_GLOBAL)
      local = .false.
    case default
      local = deck%integrator%rotation == ROTATION_EXACT
    end select
  end subroutine choose_event_loop

  !> Reads a checkpoint and checks, before any output is touched, that this run can
  !> continue from it (restart_check): it is intact (digest), not at or past t_end, made
  !> by this deck (bodies, shapes, physics), its state sane and free of overlaps. Then the
  !> saved state replaces the deck's in bodies (all bodies, global-id order).
  subroutine restore_checkpoint(self, par, path, bodies, meta, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    type(bodies_t), intent(inout) :: bodies
    type(checkpoint_meta_t), intent(out) :: meta
    type(error_t), intent(inout) :: err
    type(checkpoint_meta_t) :: expected
    type(bodies_t) :: saved
    type(deck_change_t) :: changes
    real(dp) :: box
    integer :: i, j

    call read_checkpoint(par, path, meta, saved, err)
    if (err%failed()) return
    if (.not. (meta%time < self%deck%run%t_end)) then
      call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"' is at t = "//str(meta%time, '(es10.3)')// &
                   ' s, not before &run t_end = '//str(self%deck%run%t_end, '(es10.3)')//' s of '//self%deck%path// &
                   ': nothing left to run (raise t_end to continue the run)')
      return
    end if
    expected%n_bodies_total = self%n_total
    expected%title = self%deck%run%title
    expected%checksum = bodies_checksum_serial(bodies)
    call check_checkpoint_matches(meta, expected, path, err)
    if (err%failed()) return
    ! (every rank compares all of the lines: the same notices and refusals on every rank;
    ! its share is taken back from them after, so that only one copy is held meanwhile)
    block
      character(len=:), allocatable :: all_lines(:)
      integer(i8) :: first
      integer :: n_mine
      if (par%n_ranks > 1) then
        n_mine = size(self%deck_lines)
        first = par%exscan(int(n_mine, i8))
        call par%allgather_lines(self%deck_lines, all_lines)
        deallocate (self%deck_lines)
        call compare_decks(meta%deck_lines, all_lines, path, changes, err)
        self%deck_lines = all_lines(first + 1:first + n_mine)
      else
        call compare_decks(meta%deck_lines, self%deck_lines, path, changes, err)
      end if
    end block
    ! (read for the comparison only: 190 MB at 100,000 bodies)
    if (allocated(meta%deck_lines)) deallocate (meta%deck_lines)
    if (err%failed()) return
    call check_same_bodies(self%deck, meta, saved, self%shapes, bodies, path, err)
    if (err%failed()) return
    box = smallest_moving_extent(self%shapes, bodies)
    if (box == huge(1.0_dp)) box = 1.0_dp
    call check_restored_state(self%deck, saved, box, path, err)
    if (err%failed()) return
    do j = 1, saved%n_owned
      i = int(saved%gid(j))
      call copy_row(saved, j, bodies, i)
    end do
    call check_initial_overlaps(self%deck, self%shapes, bodies, err, par=par)
    if (err%failed()) then
      call err%prefix("checkpoint '"//trim(path)//"': ")
      return
    end if
    if (par%is_root()) then
      do i = 1, size(changes%notices)
        write (*, '(a)') '  restart notice: '//trim(changes%notices(i))
      end do
      if (changes%n_allowed > 0) then
        write (*, '(a)') '  the deck changed '//str(changes%n_allowed)//' output or end-time variable(s): the '// &
          'continuation is not bitwise the uninterrupted run'
      else
        write (*, '(a)') '  the deck is unchanged: the run continues bitwise as the uninterrupted run'
      end if
      flush (output_unit)
    end if
  end subroutine restore_checkpoint

  !> Whether contacts between bodies of different ranks are built for this deck: no contact
  !> passes or islands (no gravity, every pair's restitution above 0), the local loop.
  logical function cross_contacts_built(deck, collisions) result(built)
    type(deck_t), intent(in) :: deck
    type(collision_stage_t), intent(in) :: collisions
    built = norm2(deck%run%gravity) == 0.0_dp
    if (allocated(collisions%materials%restitution)) then
      if (size(collisions%materials%restitution) > 0) built = built .and. minval(collisions%materials%restitution) > 0.0_dp
    end if
  end function cross_contacts_built

  !> The fixed bodies of all (global-id order), held by every rank of cross_windows.
  subroutine take_statics(all, statics)
    type(bodies_t), intent(in) :: all
    type(bodies_t), intent(inout) :: statics
    integer :: i
    call statics%append_rows(all, pack([(i, i=1, all%n_owned)], all%fixed(1:all%n_owned)), .false.)
  end subroutine take_statics

  !> The deck fingerprint of bodies held whole on every rank (no reduction needed).
  real(dp) function bodies_checksum_serial(bodies) result(checksum)
    type(bodies_t), intent(in) :: bodies
    type(parallel_t) :: one_rank
    checksum = bodies_checksum(one_rank, bodies)
  end function bodies_checksum_serial

  !> Rows first..last of all (global ids in order) become the owned bodies of this rank.
  subroutine take_rows(all, first, last, owned)
    type(bodies_t), intent(in) :: all
    integer(i8), intent(in) :: first, last
    type(bodies_t), intent(inout) :: owned
    integer :: i, n
    n = int(max(0_i8, last - first + 1))
    call owned%allocate(n)
    do i = 1, n
      call copy_row(all, int(first) + i - 1, owned, i)
    end do
    owned%n_owned = n
    owned%n_ghost = 0
  end subroutine take_rows

  !> Continues from a checkpoint (restore_checkpoint has checked it and restored bodies).
  subroutine restart_from(self, meta, is_root)
    class(simulation_t), intent(inout) :: self
    type(checkpoint_meta_t), intent(in) :: meta
    logical, intent(in) :: is_root
    self%time = meta%time
    self%step = meta%step
    self%first_step = meta%step
    self%next_output = meta%next_output_time
    self%next_checkpoint = meta%next_checkpoint_time
    self%wall_before = meta%wall_time_before
    ! The initial totals, for the conservation errors (counters: see fill_meta).
    self%initial%kinetic_translational = counter(meta, 'initial_kinetic_translational')
    self%initial%kinetic_rotational = counter(meta, 'initial_kinetic_rotational')
    self%initial%potential = counter(meta, 'initial_potential')
    self%max_energy_error = counter(meta, 'max_energy_error')
    self%max_momentum_error = counter(meta, 'max_momentum_error')
    self%max_angular_momentum_error = counter(meta, 'max_angular_momentum_error')
    ! (totals over every rank: rank 0 carries them on, the others count from zero, so the
    ! sums of the history and the summary are the totals on any number of ranks)
    if (is_root) then
      self%collisions%stats%events = nint(counter(meta, 'events'), i8)
      self%collisions%stats%contacts = nint(counter(meta, 'contacts'), i8)
      self%collisions%stats%advancement_iterations = nint(counter(meta, 'advancement_iterations'), i8)
      self%collisions%stats%pair_tests = nint(counter(meta, 'pair_tests'), i8)
    end if
    self%collisions%stats%min_separation = counter(meta, 'min_separation')
    self%initial%momentum = meta%p0
    self%initial%angular_momentum = meta%l0
    self%initial%mass = meta%mass0
    call self%frames%restore(meta%n_frames, meta%frame_times)
    self%restarted = .true.
  end subroutine restart_from

  !> A named counter of a checkpoint (0 if absent).
  pure real(dp) function counter(meta, name)
    type(checkpoint_meta_t), intent(in) :: meta
    character(len=*), intent(in) :: name
    integer :: k
    counter = 0.0_dp
    if (.not. allocated(meta%counter_names)) return
    do k = 1, size(meta%counter_names)
      if (meta%counter_names(k) == name) counter = meta%counters(k)
    end do
  end function counter

  subroutine simulation_free(self)
    class(simulation_t), intent(inout) :: self
    call self%bodies%free()
    call self%shapes%free()
  end subroutine simulation_free

end module simulation
