!> The local event loop (`&integrator events = 'local'`, docs/architecture.md "Local
!> events"): the cost of a collision is that of the bodies it changes, not of the scene.
!>
!>  - Bodies are not stepped. Each is its anchor (the state at its last change of trajectory)
!>    plus its exact flow (free_flight, exact mode), evaluated at the time an event, a frame
!>    or a checkpoint needs it. A trajectory version per body counts its changes.
!>  - Every candidate pair (cell_grid: the bodies' regions overlap) keeps a certificate in
!>    pair_store: a time before which it cannot reach its aim, from its last closest-point
!>    query and both bodies' motion bounds, stamped with both versions. One priority queue
!>    per kind of event (pairs, box crossings, islands; event_queue) orders them; a pair is
!>    queried again only when its certificate comes due or a version changes.
!>  - An impact changes the bodies of its impulse group (the band contacts connected to the
!>    pair through moving bodies): only their anchors, pairs and regions are updated.
!>  - Bodies held by a contact pass form islands (contact/islands), each stepping with its
!>    own step from its own clock, with the global loop's contact pass, distance correction
!>    and sleeping restricted to it; every other island and every free body goes on
!>    without it. An impact on an island cuts its step there (the pass's unused part is
!>    taken back, as the global loop does when an event cuts its step).
!> Events at one time are taken pairs and crossings first (by global ids), then the
!> outputs (the caller's, at the stop time), then island steps, so that a checkpoint sees
!> what a restart from it sees.
module event_loop
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_NUMERIC, ERR_INTERNAL
  use string_utils, only: str
  use input_config, only: integrator_config_t
  use shape, only: shape_library_t, SHAPE_SPHERE
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use collision_stage, only: collision_stage_t, collision_stats_t, turning_reach
  use impulse_solver, only: impulse_stats_t
  use contact_solver, only: pgs_stats_t
  use pair_geometry, only: pair_gap, point_box_gap, convex_pair, convex_pair_bound
  use advancement_bound, only: closing_bound_t, time_to_close
  use time_of_contact, only: advancement_result_t
  use pair_store, only: pair_store_t, ACTION_NONE, ACTION_QUERY, ACTION_IMPACT, ACTION_ENTER
  use event_queue, only: event_queue_t
  use row_journal, only: row_journal_t
  use cell_grid, only: cell_grid_t, cell_lists_t
  use islands, only: island_table_t, body_islands
  use sorting, only: sort_index_keys
  implicit none
  private
  public :: event_loop_t, event_stats_t, copy_loop
  public :: CROSS_OFF, CROSS_SPECULATE, CROSS_RERUN, CROSS_PHASE, STOP_NONE, STOP_CROSS, STOP_HALO

  !> Ghost rows (docs/architecture.md, "Cross-rank contacts"): rows after bodies%n_owned
  !> are other ranks' bodies. cross_mode says what an event that needs one of them (an
  !> impact of a pair with a moving ghost, or an impulse group reaching one) does:
  !> CROSS_OFF, no ghosts; CROSS_SPECULATE, it is taken here as any impact, the ghosts'
  !> copies given new trajectories too ("Cross-rank impacts computed twice": the other rank
  !> takes it as well, and the window's end compares the two ranks' change logs), unless
  !> its impulse group reaches a ghost whose neighbourhood is not all held here; then the
  !> run stops there (stop_kind STOP_CROSS) and, as it does at a box crossing of an owned
  !> body near a neighbouring brick (STOP_HALO), leaves the rest to the caller's window (the
  !> state is then the caller's to restore); CROSS_RERUN, as CROSS_SPECULATE before
  !> rerun_to (a stop there is an internal error: a run repeated up to a time before it),
  !> a stop from rerun_to on; CROSS_PHASE, impacts whose pair's lower global id is owned
  !> here are taken with the ghosts (their new trajectories are the caller's to send to
  !> their owners), the others dropped (their owners take them).
  integer, parameter :: CROSS_OFF = 0, CROSS_SPECULATE = 1, CROSS_RERUN = 2, CROSS_PHASE = 3
  integer, parameter :: STOP_NONE = 0, STOP_CROSS = 1, STOP_HALO = 2
  integer, parameter :: CROSS_GO = 0, CROSS_STOP = 1, CROSS_DROPPED = 2

  !> "Never" [s]: later than any run, far from overflow in t + dt.
  real(dp), parameter :: far_future = 1.0e30_dp
  !> words of a body's row in the loop's row journal (touch_row)
  integer, parameter :: LOOP_ROW_WORDS = 16
  !> Closest-point queries one certificate may spend before it is queued again (a pair that
  !> converges slowly is then re-examined lazily, and may be invalidated before that).
  integer, parameter :: queries_per_certificate = 16
  !> A certificate by conservative advancement reaches at most this many dt_max ahead.
  real(dp), parameter :: lookahead_steps = 10.0_dp

  type :: event_stats_t
    integer(i8) :: impacts = 0           !< impact events
    integer(i8) :: certificates = 0      !< pair certificates computed
    integer(i8) :: far_certificates = 0  !< of them from bounding volumes alone (no closest points)
    integer(i8) :: island_steps = 0      !< island steps taken
    integer(i8) :: body_steps = 0        !< members stepped, summed over island steps
    integer(i8) :: island_cuts = 0       !< island steps cut short by an impact
    integer(i8) :: crossings = 0         !< bodies placed again in the grid (box crossings)
    integer(i8) :: evaluations = 0       !< bodies evaluated from their anchors for events
    integer(i8) :: output_evaluations = 0  !< ... for frames, history rows and checkpoints
    integer(i8) :: trajectory_changes = 0  !< anchors taken after a change (version increments)
    integer(i8) :: enters = 0            !< free pairs that came within reach of a contact pass
    integer(i8) :: joins = 0             !< free bodies that joined an island at its next step
    integer(i8) :: holds = 0             !< island steps whose pass was held to repeated impacts
    !> cross-rank impacts taken in a window's speculative run on this rank, which owns the
    !> pair's lower global id (the other rank takes each too, uncounted)
    integer(i8) :: cross_impacts = 0
    ! Wall time by kind of event [s] (the summary's time by phase):
    real(dp) :: wall_detection = 0.0_dp  !< pair events without an impact (certificates) and box crossings
    real(dp) :: wall_impacts = 0.0_dp    !< pair events that ended in an impact (certificate + impulses)
    real(dp) :: wall_islands = 0.0_dp    !< island steps (contact passes of resting islands)
  end type event_stats_t

  type :: event_loop_t
    real(dp) :: time = 0.0_dp             !< every event before this has been processed [s]
    real(dp) :: gravity(3) = 0.0_dp
    real(dp) :: dt_max = 0.0_dp
    real(dp) :: t_hard = huge(1.0_dp)     !< island steps end here (checkpoint or end) [s]
    real(dp) :: margin = 0.0_dp           !< region margin of a moving body [m]
    real(dp) :: near = 0.0_dp             !< closer than this a pair gets closest points [m]
    real(dp) :: band = 0.0_dp             !< contact band: target + tolerance + contact tolerance [m]
    logical :: use_pass = .false.         !< gravity or inelastic pairs: contact passes and islands
    type(integrator_config_t) :: config
    !> (allocatable so that a cross-rank window's save copies the loop without them: they keep
    !> undo journals instead, see copy_loop; loop_init allocates them)
    type(pair_store_t), allocatable :: pairs
    type(event_queue_t), allocatable :: pair_queue, body_queue
    type(event_queue_t) :: island_queue
    type(cell_grid_t) :: cells
    type(island_table_t) :: islands
    integer(i8), allocatable :: version(:)       !< trajectory version per body
    integer(i8), allocatable :: changes(:)       !< trajectory changes per body, this run
    real(dp), allocatable :: state_time(:)       !< time bodies%x, q, v, w of the body hold [s]
    real(dp), allocatable :: expiry(:)           !< its trajectory is certain until here [s]
    real(dp), allocatable :: region_x(:, :)      !< centre it was placed at in the grid [m]
    integer, allocatable :: island_of(:)         !< island slot, 0 if in none
    !> When an island step last let the body go free (a member it did not keep) [s]: a pair
    !> of such a body is not entered into an island step again at that same time (see certify)
    real(dp), allocatable :: released_at(:)
    integer, allocatable :: mark(:)              !< per body: scratch stamps
    integer, allocatable :: pair_mark(:)         !< per pair slot: scratch stamps
    integer :: stamp = 0
    integer :: zero_impacts = 0                  !< consecutive impacts that changed nothing
    !> The last impact (pair by global ids, time) and how many times in a row it came again
    !> at that same time: a pair that an island's pass leaves approaching inside the band
    !> is found in contact again at once (a livelock the zero_impacts guard does not see,
    !> since each impulse does change the velocities the pass then changes back)
    integer(i8) :: last_impact_pair(2) = 0
    real(dp) :: last_impact_time = -1.0_dp
    integer :: repeated_impacts = 0
    !> The pairs (slots) that had an impact at impacts_now_time: a pair found in contact
    !> again at that time gets the island step after it held to all of them (see impact)
    integer, allocatable :: impacts_now(:)
    integer :: n_impacts_now = 0
    real(dp) :: impacts_now_time = -1.0_dp
    !> Island steps taken at steps_now_time: past 100 + 4 per body, time has stopped
    !> passing (a cycle of steps no guard above names) and the run stops with an error
    integer :: steps_now = 0
    real(dp) :: steps_now_time = -1.0_dp
    type(event_stats_t) :: stats
    integer, allocatable :: found(:)
    ! cross-rank windows (see CROSS_OFF ...)
    integer :: cross_mode = CROSS_OFF
    integer :: n_owned = 0                       !< rows 1..n_owned owned, the rest ghosts
    integer :: stop_kind = STOP_NONE             !< why run_until stopped early
    real(dp) :: stop_time = far_future           !< ... and when [s]
    integer(i8) :: stop_pair(2) = 0              !< the pair (global ids) of a STOP_CROSS
    integer, allocatable :: stop_rows(:)         !< ... and the moving ghosts it needs (rows)
    integer :: n_stop_rows = 0
    !> CROSS_RERUN: an impact needing a ghost at or after this time stops the run (the
    !> caller's repeated run ends there, this rank's events at it left for the next window);
    !> before it, one is an internal error [s]
    real(dp) :: rerun_to = far_future
    !> per row: when the ghost's owner changed its trajectory in this window (far_future: not,
    !> or not known); a cross phase's impulse group with a ghost changed by then is left to
    !> the next window, whose ghosts are fresh [s]
    real(dp), allocatable :: ghost_changed_at(:)
    integer(i8) :: deferred = 0                  !< cross-phase impacts left to the next window
    !> ghost rows whose pair a cross phase dropped (the caller makes them come again afresh)
    integer, allocatable :: dropped_rows(:)
    integer :: n_dropped_rows = 0
    !> a pair of two bodies neither of which this rank owns and moves (held_pair) may be in
    !> the store: made by a cross phase for a ghost of its impulse group
    logical :: foreign_pairs = .false.
    !> Placing an owned body in the grid (a box crossing, or an event that moved its region)
    !> is a STOP_HALO (the ghosts the rank holds may no longer cover what can reach it, or a
    !> neighbour may not hold it while it can reach the neighbour's bodies) where it is
    !> within two boxes of a side with a neighbour (outside [watch_lo, watch_hi]) that it was
    !> not within at the window's start (zone_sides: bit 2k-2 the lower side of axis k, bit
    !> 2k-1 the upper: the sides the halo exchange sent it to), or, sent to some, outside its
    !> own brick [brick_lo, brick_hi] [m]
    real(dp) :: watch_lo(3) = -far_future, watch_hi(3) = far_future
    real(dp) :: brick_lo(3) = -far_future, brick_hi(3) = far_future
    integer, allocatable :: zone_sides(:)
    !> A placement of an owned body found it outside what the halo covers (the condition of
    !> STOP_HALO) in this window, in any cross mode (a cross phase or a repeated run does not
    !> stop for it): the next window's start must send it to the neighbours it came near
    !> (halo_seen), or, if it left its own brick (halo_exit_seen), start in full, with
    !> migration and the whole halo
    logical :: halo_seen = .false.
    logical :: halo_exit_seen = .false.
    !> a ghost in an impulse group of the cross phase must lie in [complete_lo, complete_hi]:
    !> every body within the band of it is then held here [m]
    real(dp) :: complete_lo(3) = -far_future, complete_hi(3) = far_future
    real(dp), allocatable :: first_change(:)     !< per body: first trajectory change since init [s]
    !> per owned row, in a cross-rank window: the box its centre of mass swept from its first
    !> change on (to the last change; path_close adds the rest) [m]
    real(dp), allocatable :: path_lo(:, :), path_hi(:, :)
    !> CROSS_SPECULATE: the change log, every new trajectory of a row another rank holds (a
    !> ghost, or an owned body with zone_sides) in the order taken: row, time [s] and flight
    !> record (free_flight%record_of), for the window's comparison with the other ranks'
    integer :: n_change_log = 0
    integer, allocatable :: change_log_row(:)
    real(dp), allocatable :: change_log_time(:)
    integer(i8), allocatable :: change_log_words(:, :)
    !> An undo journal of the per-body rows (version, changes, state_time, expiry,
    !> region_x, island_of, released_at, first_change, path_lo, path_hi: LOOP_ROW_WORDS words) for
    !> a cross-rank window's save (copy_loop): the copy then carries none of them, nor the
    !> scratch marks (8 MB a window for a rank of a 100,000-sphere gas). touch_row keeps a
    !> row before its first change. (Allocatable: the copy does not carry it either.)
    type(row_journal_t), allocatable :: row_journal
  contains
    procedure :: init => loop_init
    procedure :: remap_bodies => loop_remap_bodies
    procedure :: run_until => loop_run_until
    procedure :: synchronize => loop_synchronize
    procedure :: next_event_time => loop_next_event_time
    procedure :: bodies_unchanged => loop_bodies_unchanged
    procedure :: take_trajectories => loop_take_trajectories
    procedure :: take_ghost_trajectories => loop_take_ghost_trajectories
    procedure :: start_cross_window => loop_start_cross_window
    procedure :: zone_sides_of => loop_zone_sides_of
    procedure :: close_paths => loop_close_paths
    procedure :: queued_halo_time => loop_queued_halo_time
    procedure :: stop_journal => loop_stop_journal
  end type event_loop_t

contains

  !> Builds the loop from the state in bodies at time t: every moving body anchored there,
  !> placed in the grid, every candidate pair certified, and (with contact passes) the
  !> islands of the bodies within reach of one another stepped once. The same at the start,
  !> at a restart and after a checkpoint, so that a restart continues as the run did.
  !> t_hard: island steps end there (the next checkpoint or the end) [s].
  !> keep_anchors: bodies already anchored keep their anchors (their state at t in bodies
  !> evaluated from them): the loop is rebuilt after a migration changed which bodies this
  !> rank holds, and the trajectories go on bit for bit as on one rank.
  subroutine loop_init(self, stage, bodies, shapes, flight, gravity, config, t, dt_max, t_hard, err, keep_anchors)
    class(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: gravity(3), t, dt_max, t_hard
    type(integrator_config_t), intent(in) :: config
    type(error_t), intent(inout) :: err
    logical, intent(in), optional :: keep_anchors
    logical :: keep
    integer :: n, i, j, k, slot
    integer, allocatable :: seeds(:)
    integer :: n_seeds
    keep = .false.
    if (present(keep_anchors)) keep = keep_anchors
    n = bodies%n_owned + bodies%n_ghost
    ! (a journal's rows mean nothing in a loop built again)
    if (allocated(self%row_journal)) call self%row_journal%stop()
    self%time = t
    self%gravity = gravity
    self%config = config
    self%dt_max = dt_max
    self%t_hard = t_hard
    self%band = stage%target + stage%tolerance + stage%contact_tolerance
    ! A body moves at most half a grid box before it is placed again; two bodies within
    ! the band of each other always have overlapping regions.
    self%margin = 0.5_dp*stage%box_size
    self%near = 0.25_dp*stage%box_size + 2.0_dp*self%band
    self%use_pass = norm2(gravity) > 0.0_dp
    stage%resting%persistent = .true.
    if (allocated(stage%materials%restitution)) then
      if (size(stage%materials%restitution) > 0) self%use_pass = self%use_pass .or. &
                                                                minval(stage%materials%restitution) <= 0.0_dp
    end if
    if (allocated(self%version)) then
      if (size(self%version) < n) deallocate (self%version, self%changes)
    end if
    if (.not. allocated(self%version)) then
      allocate (self%version(n), self%changes(n))
      self%version = 0
      self%changes = 0
    end if
    if (allocated(self%state_time)) deallocate (self%state_time, self%expiry, self%region_x, self%island_of, &
                                                self%released_at, self%mark)
    allocate (self%state_time(n), self%expiry(n), self%region_x(3, n), self%island_of(n), self%released_at(n), &
              self%mark(n))
    self%state_time = t
    self%expiry = far_future
    self%island_of = 0
    self%released_at = -far_future
    self%mark = 0
    self%stamp = 0
    self%zero_impacts = 0
    self%repeated_impacts = 0
    self%last_impact_time = -1.0_dp
    self%n_impacts_now = 0
    self%impacts_now_time = -1.0_dp
    self%steps_now = 0
    self%steps_now_time = -1.0_dp
    self%n_owned = bodies%n_owned
    self%stop_kind = STOP_NONE
    self%stop_time = far_future
    self%n_stop_rows = 0
    if (allocated(self%ghost_changed_at)) deallocate (self%ghost_changed_at)
    if (allocated(self%first_change)) deallocate (self%first_change)
    allocate (self%first_change(n))
    self%first_change = far_future
    if (.not. allocated(self%pairs)) allocate (self%pairs)
    if (.not. allocated(self%pair_queue)) allocate (self%pair_queue)
    if (.not. allocated(self%body_queue)) allocate (self%body_queue)
    call self%pairs%init(n, 8*n)
    if (allocated(self%pair_mark)) deallocate (self%pair_mark)
    allocate (self%pair_mark(0))
    call self%pair_queue%init(8*n)
    call self%body_queue%init(n)
    call self%island_queue%init(16)
    call self%islands%init()
    call init_cells(self, bodies, shapes, stage%box_size, n, err)
    if (err%failed()) return
    call stage%reserve_table(16, n)
    do i = 1, n
      if (.not. bodies%fixed(i)) then
        if (.not. (keep .and. flight%is_anchored(i))) call flight%anchor_at(bodies, i, t)
        self%version(i) = self%version(i) + 1
      end if
      call place(self, bodies, shapes, i, err)
      if (err%failed()) return
    end do
    ! candidate pairs: every moving body asks the grid (static-static pairs are never made)
    do i = 1, n
      if (bodies%fixed(i)) cycle
      call self%cells%query(i, self%found, k, n)
      do j = 1, k
        if (.not. held_pair(self, bodies, i, self%found(j))) cycle
        if (self%pairs%find(i, self%found(j)) > 0) cycle
        slot = self%pairs%add(i, self%found(j), bodies%gid(i), bodies%gid(self%found(j)))
      end do
    end do
    call ensure_pair_marks(self)
    do slot = 1, self%pairs%n_slots
      if (self%pairs%a(slot) == 0) cycle
      call certify(self, stage, bodies, shapes, flight, slot, t, err)
      if (err%failed()) return
    end do
    do i = 1, n
      if (.not. bodies%fixed(i)) call schedule_crossing(self, bodies, flight, i, t)
    end do
    if (.not. self%use_pass) return
    ! The bodies within reach of a contact pass take their first island step now.
    allocate (seeds(n))
    n_seeds = 0
    do i = 1, n
      if (bodies%fixed(i)) cycle
      if (has_pass_pair(self, stage, bodies, shapes, flight, i, t)) then
        n_seeds = n_seeds + 1
        seeds(n_seeds) = i
      end if
    end do
    if (n_seeds == 0) return
    ! (queued, not taken here: the outputs at t come first, as in the global loop)
    slot = self%islands%add(seeds(1:n_seeds), t, 0.0_dp, 0.0_dp)
    allocate (self%islands%islands(slot)%band_pairs(2, 1))
    self%islands%islands(slot)%n_band_pairs = 0
    self%island_of(seeds(1:n_seeds)) = slot
    call self%island_queue%set(slot, t, bodies%gid(seeds(1)), 0_i8)
  end subroutine loop_init

  !> After a migration changed which bodies this rank holds, at time t (docs/architecture.md,
  !> "The loop through a migration"): body i is now new_index(i), 0 if it left; versions(k)
  !> is the trajectory version of row k now (migration carried it with the body); every
  !> moving body's state in bodies is its anchor evaluated at t. Instead of building the loop
  !> again (init), what the bodies that stayed have is kept: their anchors, versions,
  !> regions and grid boxes, box-crossing times, islands with their clocks, and every pair of
  !> two of them with its certificate and queue entry (renamed, not computed again). Pairs
  !> with a body that left are dropped; arrivals are placed in the grid and their pairs made
  !> and certified, and with contact passes an arrival within reach of one takes an island
  !> step at t, as init's bodies do. The cost is that of the arrivals' pairs plus renaming
  !> O(bodies + pairs), not one certificate per pair.
  !> An island that lost a member or a band pair's body (split between ranks) cannot go on
  !> here: then the loop is built again as init builds it (keep_anchors), the rule before
  !> this existed, and rebuilt is true.
  subroutine loop_remap_bodies(self, stage, bodies, shapes, flight, new_index, versions, t, t_hard, err, rebuilt)
    class(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: new_index(:)
    integer(i8), intent(in) :: versions(:)
    real(dp), intent(in) :: t, t_hard
    type(error_t), intent(inout) :: err
    logical, intent(out) :: rebuilt
    integer :: n, i, ni, k, j, slot, n_found, n_new_slots, n_moved, n_kept_now, n_seeds
    integer, allocatable :: old_of(:), dropped(:), new_slots(:), moved(:), seeds(:)
    integer(i8), allocatable :: changes(:)
    real(dp), allocatable :: expiry(:), region_x(:, :), released_at(:), state_time(:)
    integer, allocatable :: island_of(:)
    logical :: kept
    n = bodies%n_owned + bodies%n_ghost
    self%n_owned = bodies%n_owned
    rebuilt = .false.
    ! (a journal's rows mean nothing after a renumbering)
    if (allocated(self%row_journal)) call self%row_journal%stop()
    call self%islands%remap_bodies(new_index, kept)
    if (.not. kept) then
      rebuilt = .true.
      allocate (changes(max(n, 1)))
      changes = 0
      do i = 1, min(size(new_index), size(self%changes))
        if (new_index(i) > 0) changes(new_index(i)) = self%changes(i)
      end do
      call move_alloc(changes, self%changes)
      if (allocated(self%version)) deallocate (self%version)
      allocate (self%version(max(n, 1)))
      self%version = 0
      self%version(1:n) = versions(1:n)
      call stage%remap_bodies(new_index, n)
      call self%init(stage, bodies, shapes, flight, self%gravity, self%config, t, self%dt_max, t_hard, err, &
                     keep_anchors=.true.)
      return
    end if
    self%time = t
    self%t_hard = t_hard
    ! the per-body arrays follow their bodies; arrivals (old_of = 0) start as init starts a body
    allocate (old_of(n))
    old_of = 0
    do i = 1, size(new_index)
      if (new_index(i) > 0) old_of(new_index(i)) = i
    end do
    allocate (changes(max(n, 1)), expiry(n), region_x(3, n), island_of(n), released_at(n))
    do ni = 1, n
      i = old_of(ni)
      if (i > 0) then
        changes(ni) = self%changes(i)
        expiry(ni) = self%expiry(i)
        region_x(:, ni) = self%region_x(:, i)
        island_of(ni) = self%island_of(i)
        released_at(ni) = self%released_at(i)
      else
        changes(ni) = 0
        expiry(ni) = far_future
        region_x(:, ni) = bodies%x(:, ni)
        island_of(ni) = 0
        released_at(ni) = -far_future
      end if
    end do
    call move_alloc(changes, self%changes)
    call move_alloc(expiry, self%expiry)
    call move_alloc(region_x, self%region_x)
    call move_alloc(island_of, self%island_of)
    call move_alloc(released_at, self%released_at)
    ! (a row that stayed keeps the time its state was evaluated at: at a full start every
    ! row was evaluated at t, at a light start's arrivals most rows are where their last
    ! event left them, and sync must evaluate those before they are used at t)
    allocate (state_time(n))
    do ni = 1, n
      state_time(ni) = t
      i = old_of(ni)
      if (i > 0 .and. i <= size(self%state_time)) state_time(ni) = self%state_time(i)
    end do
    call move_alloc(state_time, self%state_time)
    deallocate (self%version, self%mark)
    allocate (self%version(max(n, 1)), self%mark(n))
    self%version = 0
    self%version(1:n) = versions(1:n)
    self%mark = 0
    do ni = 1, n
      if (old_of(ni) == 0 .and. .not. bodies%fixed(ni)) self%version(ni) = self%version(ni) + 1
    end do
    ! the grid, the pairs and the queues renamed; pairs with a body that left dropped
    call self%cells%remap_bodies(new_index, n)
    call self%pairs%remap_bodies(new_index, n, dropped, k)
    do j = 1, k
      call self%pair_queue%remove(dropped(j))
    end do
    if (self%n_impacts_now > 0) then
      n_kept_now = 0
      do j = 1, self%n_impacts_now
        if (self%pairs%a(self%impacts_now(j)) == 0) cycle
        n_kept_now = n_kept_now + 1
        self%impacts_now(n_kept_now) = self%impacts_now(j)
      end do
      self%n_impacts_now = n_kept_now
    end if
    if (allocated(self%pair_mark)) self%pair_mark = 0
    call self%body_queue%remap_handles(new_index, n)
    call stage%remap_bodies(new_index, n)
    ! arrivals anchored (a body in flight between events is) and placed, and their pairs made
    ! (static-static pairs never are)
    allocate (moved(16), new_slots(16))
    n_moved = 0
    n_new_slots = 0
    do ni = 1, n
      if (old_of(ni) > 0) cycle
      if (.not. bodies%fixed(ni)) then
        if (.not. flight%is_anchored(ni)) call flight%anchor_at(bodies, ni, t)
        call push(moved, n_moved, ni)
      end if
      call place(self, bodies, shapes, ni, err)
      if (err%failed()) return
    end do
    do ni = 1, n
      if (old_of(ni) > 0) cycle
      call self%cells%query(ni, self%found, n_found, n)
      do k = 1, n_found
        j = self%found(k)
        if (.not. held_pair(self, bodies, ni, j)) cycle
        if (self%pairs%find(ni, j) > 0) cycle
        slot = self%pairs%add(ni, j, bodies%gid(ni), bodies%gid(j))
        call push(new_slots, n_new_slots, slot)
      end do
    end do
    call ensure_pair_marks(self)
    call sort_slots(self, bodies, new_slots, n_new_slots)
    do k = 1, n_new_slots
      call certify(self, stage, bodies, shapes, flight, new_slots(k), t, err)
      if (err%failed()) return
    end do
    ! (a guard: a body that stayed holds an anchor between events; one without is anchored
    ! at t, a new trajectory, placed again and all of its pairs certified from t)
    do ni = 1, n
      if (old_of(ni) == 0 .or. bodies%fixed(ni)) cycle
      if (flight%is_anchored(ni)) cycle
      call flight%anchor_at(bodies, ni, t)
      self%version(ni) = self%version(ni) + 1
      call replace(self, stage, bodies, shapes, flight, ni, t, err)
      if (err%failed()) return
      call certify_pairs_of(self, stage, bodies, shapes, flight, [ni], t, err)
      if (err%failed()) return
      call push(moved, n_moved, ni)
    end do
    do k = 1, n_moved
      call schedule_crossing(self, bodies, flight, moved(k), t)
    end do
    if (self%use_pass) then
      ! arrivals within reach of a contact pass take an island step at t, as init's bodies do
      allocate (seeds(n_moved))
      n_seeds = 0
      do k = 1, n_moved
        i = moved(k)
        if (self%island_of(i) /= 0 .or. old_of(i) > 0) cycle
        if (has_pass_pair(self, stage, bodies, shapes, flight, i, t)) then
          n_seeds = n_seeds + 1
          seeds(n_seeds) = i
        end if
      end do
      if (n_seeds > 0) then
        slot = self%islands%add(seeds(1:n_seeds), t, 0.0_dp, 0.0_dp)
        if (allocated(self%islands%islands(slot)%band_pairs)) deallocate (self%islands%islands(slot)%band_pairs)
        allocate (self%islands%islands(slot)%band_pairs(2, 1))
        self%islands%islands(slot)%n_band_pairs = 0
        self%island_of(seeds(1:n_seeds)) = slot
        call self%island_queue%set(slot, t, bodies%gid(seeds(1)), 0_i8)
      end if
    end if
    if (self%config%audit_certificates) call audit_certificates(self, bodies, t, err)
  end subroutine loop_remap_bodies

  !> The earliest pending event of any kind [s] (far_future if none).
  pure real(dp) function loop_next_event_time(self) result(t)
    class(event_loop_t), intent(in) :: self
    t = min(self%pair_queue%top_time(), self%body_queue%top_time(), self%island_queue%top_time())
  end function loop_next_event_time

  !> Processes every event before t_stop, and the pair and crossing events at t_stop
  !> (island steps at t_stop come after the caller's outputs there). t_hard: island steps
  !> end there from now on (the next checkpoint or the end of the run) [s].
  !> exclusive: none at t_stop either. With ghosts (cross_mode CROSS_SPECULATE) the run may
  !> stop before t_stop: stop_kind and stop_time say why and when.
  subroutine loop_run_until(self, stage, bodies, shapes, flight, t_stop, t_hard, err, exclusive)
    class(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: t_stop, t_hard
    type(error_t), intent(inout) :: err
    logical, intent(in), optional :: exclusive
    real(dp) :: t_pair, t_body, t_island, t
    integer :: handle
    integer(i8) :: clock, clock_rate, impacts_before
    logical :: up_to, due
    up_to = .false.
    if (present(exclusive)) up_to = exclusive
    self%t_hard = t_hard
    self%stop_kind = STOP_NONE
    self%stop_time = far_future
    call system_clock(count_rate=clock_rate)
    do
      call system_clock(clock)
      t_pair = self%pair_queue%top_time()
      t_body = self%body_queue%top_time()
      t_island = self%island_queue%top_time()
      if (up_to) then
        due = min(t_pair, t_body) < t_stop
      else
        due = min(t_pair, t_body) <= t_stop
      end if
      if (due .and. min(t_pair, t_body) <= t_island) then
        if (t_pair <= t_body) then
          if (self%cross_mode /= CROSS_OFF) then
            select case (cross_impact_due(self, bodies, self%pair_queue%top(), t_pair, err))
            case (CROSS_STOP)
              exit
            case (CROSS_DROPPED)
              cycle
            end select
            if (err%failed()) return
          end if
          call self%pair_queue%pop(handle, t)
          self%time = max(self%time, t)
          impacts_before = self%stats%impacts
          call pair_event(self, stage, bodies, shapes, flight, handle, t, err)
          if (self%stats%impacts > impacts_before) then
            self%stats%wall_impacts = self%stats%wall_impacts + elapsed(clock, clock_rate)
          else
            self%stats%wall_detection = self%stats%wall_detection + elapsed(clock, clock_rate)
          end if
        else
          call self%body_queue%pop(handle, t)
          self%time = max(self%time, t)
          call crossing_event(self, stage, bodies, shapes, flight, handle, t, err)
          self%stats%wall_detection = self%stats%wall_detection + elapsed(clock, clock_rate)
        end if
      else if (t_island < t_stop) then
        call self%island_queue%pop(handle, t)
        self%time = max(self%time, t)
        call island_end(self, stage, bodies, shapes, flight, handle, t, err)
        self%stats%wall_islands = self%stats%wall_islands + elapsed(clock, clock_rate)
      else
        exit
      end if
      if (err%failed()) return
      if (self%stop_kind /= STOP_NONE) exit
      if (self%config%audit_certificates) call audit_certificates(self, bodies, t_stop, err)
      if (err%failed()) return
    end do
    if (self%stop_kind /= STOP_NONE) return
    self%time = t_stop
  end subroutine loop_run_until

  !> What to do with the pair event at the top of the queue (slot, at t) in a run with
  !> ghosts: CROSS_GO on, unless it is an impact that needs a moving ghost. Then
  !> CROSS_SPECULATE: CROSS_GO (impact() stops the run if its group is not all held here).
  !> CROSS_RERUN: CROSS_GO before rerun_to, from there the run stops before it (stop_kind
  !> STOP_CROSS; CROSS_STOP). CROSS_PHASE: taken here if the pair's deciding body
  !> (deciding_row: the lower global id, or the moving one of a pair with a fixed body) is
  !> owned here (CROSS_GO), else dropped, its owner's to take (CROSS_DROPPED: the next event
  !> is looked at).
  integer function cross_impact_due(self, bodies, slot, t, err) result(what)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: slot
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer :: a, b, decider
    what = CROSS_GO
    if (slot <= 0) return
    if (self%pairs%action(slot) /= ACTION_IMPACT) return
    if (.not. self%pairs%current(slot, self%version)) return
    a = self%pairs%a(slot)
    b = self%pairs%b(slot)
    if (.not. (is_moving_ghost(self, bodies, a) .or. is_moving_ghost(self, bodies, b))) return
    select case (self%cross_mode)
    case (CROSS_SPECULATE)
      ! (taken: impact() stops the run if its group is not all held here)
    case (CROSS_RERUN)
      if (t >= self%rerun_to) then
        what = CROSS_STOP
        call stop_for_cross(self, bodies, a, b, [a, b], t)
      end if
    case (CROSS_PHASE)
      decider = deciding_row(bodies, a, b)
      if (decider > self%n_owned) then
        ! (the deciding body's owner takes it: dropped here with its pair, which the next
        ! window's start makes again with the ghost)
        call self%pair_queue%remove(slot)
        call self%pairs%remove(slot)
        call push(self%dropped_rows, self%n_dropped_rows, decider)
        what = CROSS_DROPPED
      end if
    end select
  end function cross_impact_due

  !> The row of the pair (rows i, j) whose owner takes and counts a cross-rank impact of it:
  !> the body of the lower global id, unless one of them is fixed, when the moving one. A
  !> fixed body is owned by the rank whose brick holds its centre and held as a static
  !> ghost everywhere else, so a wall's impact with a body of another rank was counted by
  !> both (the wall's owner, the lower id, holding the body as a ghost; the body's owner,
  !> whose pair has no moving ghost): 66,507 impacts against 66,505 for the 100,000-sphere
  !> gas on 3 x 2 bricks.
  pure integer function deciding_row(bodies, i, j) result(row)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    if (bodies%fixed(i)) then
      row = j
    else if (bodies%fixed(j)) then
      row = i
    else if (bodies%gid(j) < bodies%gid(i)) then
      row = j
    else
      row = i
    end if
  end function deciding_row

  !> Whether the pair of rows i and j is this rank's to keep: one of them is an owned moving
  !> body (two ghosts, or a ghost and a fixed body, are their owners' pair; two fixed
  !> bodies nobody's).
  pure logical function held_pair(self, bodies, i, j)
    type(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i, j
    held_pair = (i <= self%n_owned .and. .not. bodies%fixed(i)) .or. (j <= self%n_owned .and. .not. bodies%fixed(j))
  end function held_pair

  !> Whether owned body i (at its present position) has left what the halo exchange at the
  !> window's start covers (see zone_sides).
  logical function halo_left(self, bodies, i)
    type(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    halo_left = halo_left_at(self, bodies%x(:, i), i)
  end function halo_left

  !> The sides of the brick whose neighbours hold owned body i as a ghost (zone_sides).
  pure integer function loop_zone_sides_of(self, i) result(sides)
    class(event_loop_t), intent(in) :: self
    integer, intent(in) :: i
    sides = 0
    if (allocated(self%zone_sides)) then
      if (i <= size(self%zone_sides)) sides = self%zone_sides(i)
    end if
  end function loop_zone_sides_of

  !> halo_left for owned body i were its centre at x [m].
  pure logical function halo_left_at(self, x, i)
    type(event_loop_t), intent(in) :: self
    real(dp), intent(in) :: x(3)
    integer, intent(in) :: i
    integer :: sides, now, k
    sides = self%zone_sides_of(i)
    now = 0
    do k = 1, 3
      if (x(k) < self%watch_lo(k)) now = ibset(now, 2*k - 2)
      if (x(k) > self%watch_hi(k)) now = ibset(now, 2*k - 1)
    end do
    halo_left_at = iand(now, not(sides)) /= 0
    if (sides /= 0) halo_left_at = halo_left_at .or. any(x < self%brick_lo) .or. any(x > self%brick_hi)
  end function halo_left_at

  !> The run stops at t for the impact of rows a and b, which needs the moving ghosts among
  !> rows(:) (STOP_CROSS).
  subroutine stop_for_cross(self, bodies, a, b, rows, t)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: a, b, rows(:)
    real(dp), intent(in) :: t
    integer :: k
    self%stop_kind = STOP_CROSS
    self%stop_time = t
    self%stop_pair = [min(bodies%gid(a), bodies%gid(b)), max(bodies%gid(a), bodies%gid(b))]
    if (allocated(self%stop_rows)) deallocate (self%stop_rows)
    allocate (self%stop_rows(size(rows)))
    self%n_stop_rows = 0
    do k = 1, size(rows)
      if (.not. is_moving_ghost(self, bodies, rows(k))) cycle
      self%n_stop_rows = self%n_stop_rows + 1
      self%stop_rows(self%n_stop_rows) = rows(k)
    end do
  end subroutine stop_for_cross

  !> Row i is another rank's moving body.
  pure logical function is_moving_ghost(self, bodies, i)
    type(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    is_moving_ghost = i > self%n_owned .and. .not. bodies%fixed(i)
  end function is_moving_ghost

  !> The loop's invariant, checked after an event (&integrator audit_certificates): every
  !> pair with a moving body holds a certificate made with both bodies' present versions and
  !> reaching at least to the next event (or t_stop): time then passes to that event, and a
  !> pair whose certificate ended before it could close unseen. Such a hole is an internal
  !> error naming the pair, not a quiet loss of the guarantees.
  subroutine audit_certificates(self, bodies, t_stop, err)
    type(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: t_stop
    type(error_t), intent(inout) :: err
    integer :: slot, a, b
    real(dp) :: t_next
    t_next = min(self%pair_queue%top_time(), self%body_queue%top_time(), self%island_queue%top_time(), t_stop)
    do slot = 1, self%pairs%n_slots
      a = self%pairs%a(slot)
      if (a == 0) cycle
      b = self%pairs%b(slot)
      if (bodies%fixed(a) .and. bodies%fixed(b)) cycle
      if (.not. self%pairs%current(slot, self%version)) then
        call err%set(ERR_INTERNAL, 'certificate audit: the pair of bodies '//str(bodies%gid(a))//' and '// &
                     str(bodies%gid(b))//' holds a stale certificate at t = '//str(self%time)//' s')
        return
      end if
      if (self%pairs%certified_until(slot) < t_next) then
        call err%set(ERR_INTERNAL, 'certificate audit: the pair of bodies '//str(bodies%gid(a))//' and '// &
                     str(bodies%gid(b))//' is certified only up to t = '//str(self%pairs%certified_until(slot))// &
                     ' s, the next event is at '//str(t_next)//' s')
        return
      end if
    end do
  end subroutine audit_certificates

  !> Wall seconds since clock (system_clock counts at clock_rate per second).
  real(dp) function elapsed(clock, clock_rate)
    integer(i8), intent(in) :: clock, clock_rate
    integer(i8) :: now
    call system_clock(now)
    elapsed = real(now - clock, dp)/real(clock_rate, dp)
  end function elapsed


  !> Every moving body evaluated at t into bodies (frames, history rows, checkpoints).
  subroutine loop_synchronize(self, bodies, flight, t)
    class(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: t
    integer :: i
    do i = 1, bodies%n_owned + bodies%n_ghost
      if (bodies%fixed(i) .or. self%state_time(i) == t) cycle
      call bodies%touch(i)
      call touch_row(self, i)
      call flight%evaluate(bodies, i, t, self%gravity)
      self%state_time(i) = t
      self%stats%output_evaluations = self%stats%output_evaluations + 1
    end do
  end subroutine loop_synchronize

  !> Owned rows list(:) took new trajectories at t that another rank computed (a cross-rank
  !> impact: their rows and flight records are set): new versions, placed again where they
  !> moved, their pairs certified again, their crossings scheduled.
  subroutine loop_take_trajectories(self, stage, bodies, shapes, flight, list, t, err)
    class(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: list(:)
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer :: k
    do k = 1, size(list)
      call count_change(self, list(k), t)
    end do
    call settle_changed(self, stage, bodies, shapes, flight, list, t, err)
  end subroutine loop_take_trajectories

  !> Ghost rows (list) whose rows and flight records were just replaced by their owners'
  !> at t, a light window start's (simulation_cross_windows light_start): each a new
  !> trajectory here, placed again (its pairs with every body held made where missing: a
  !> cross phase may have dropped one) and its pairs certified from t. First every ghost's
  !> pairs that are not this rank's are dropped (a cross phase makes them).
  subroutine loop_take_ghost_trajectories(self, stage, bodies, shapes, flight, list, t, err)
    class(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: list(:)
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer :: k, g, slot, next_slot
    ! the pairs a cross phase made on the spot for a ghost of its impulse group, with fixed
    ! bodies and other ghosts, are not this rank's (held_pair): gone, as a full start's
    ! remap drops them with the ghost's row (a scan of every ghost's pairs, only if any
    ! was made: it was 2% of a two-rank run, done at every light start)
    do g = self%n_owned + 1, merge(bodies%n_owned + bodies%n_ghost, self%n_owned, self%foreign_pairs)
      slot = self%pairs%head(g)
      do while (slot > 0)
        next_slot = self%pairs%next_of(slot, g)
        if (.not. held_pair(self, bodies, self%pairs%a(slot), self%pairs%b(slot))) then
          call self%pair_queue%remove(slot)
          call self%pairs%remove(slot)
        end if
        slot = next_slot
      end do
    end do
    self%foreign_pairs = .false.
    ! placed again whether or not they moved (a dropped pair is made again), then settled as
    ! the trajectories a cross phase brings (settle_changed: placed already, pairs certified)
    do k = 1, size(list)
      call count_change(self, list(k), t)
      call replace(self, stage, bodies, shapes, flight, list(k), t, err)
      if (err%failed()) return
    end do
    call settle_changed(self, stage, bodies, shapes, flight, list, t, err)
  end subroutine loop_take_ghost_trajectories

  !> A cross-rank window starts (after remap_bodies brought the ghosts in): nothing has
  !> changed in it yet, no stop, no swept path.
  subroutine loop_start_cross_window(self, bodies)
    class(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    if (allocated(self%first_change)) deallocate (self%first_change)
    allocate (self%first_change(bodies%n_owned + bodies%n_ghost))
    self%first_change = far_future
    if (allocated(self%path_lo)) deallocate (self%path_lo, self%path_hi)
    allocate (self%path_lo(3, bodies%n_owned), self%path_hi(3, bodies%n_owned))
    self%stop_kind = STOP_NONE
    self%stop_time = far_future
    self%halo_seen = .false.
    self%halo_exit_seen = .false.
    self%n_stop_rows = 0
    self%n_dropped_rows = 0
    self%n_change_log = 0
    if (.not. allocated(self%dropped_rows)) allocate (self%dropped_rows(8))
    if (allocated(self%ghost_changed_at)) deallocate (self%ghost_changed_at)
  end subroutine loop_start_cross_window

  !> How many bodies kept the trajectory they had when the loop was built (this run).
  pure integer function loop_bodies_unchanged(self, bodies) result(count_unchanged)
    class(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    integer :: i
    count_unchanged = 0
    do i = 1, bodies%n_owned
      if (.not. bodies%fixed(i) .and. self%changes(i) == 0) count_unchanged = count_unchanged + 1
    end do
  end function loop_bodies_unchanged

  ! ---------------------------------------------------------------------------------------
  ! bodies

  !> Body i's state at t in bodies (from its anchor; nothing for static bodies).
  subroutine sync(self, bodies, flight, i, t)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    if (bodies%fixed(i)) return
    ! (every body an event reads is synced first: what an impulse changes is kept too)
    call bodies%touch(i)
    if (self%state_time(i) == t) return
    call touch_row(self, i)
    call flight%evaluate(bodies, i, t, self%gravity)
    self%state_time(i) = t
    self%stats%evaluations = self%stats%evaluations + 1
  end subroutine sync

  !> Body i's trajectory changed at t (its state in bodies is the new one): a new anchor and
  !> version. Its pairs are the caller's to certify again.
  subroutine new_trajectory(self, bodies, flight, i, t)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    call count_change(self, i, t)
    if (allocated(self%path_lo) .and. .not. bodies%fixed(i)) then
      if (i <= size(self%path_lo, 2)) then
        if (self%first_change(i) >= far_future) then
          self%path_lo(:, i) = bodies%x(:, i)
          self%path_hi(:, i) = bodies%x(:, i)
        else
          call sweep_segment(self, flight, i, t, self%path_lo(:, i), self%path_hi(:, i))
        end if
      end if
    end if
    if (allocated(self%first_change)) then
      if (i <= size(self%first_change)) self%first_change(i) = min(self%first_change(i), t)
    end if
    if (.not. bodies%fixed(i)) call flight%anchor_at(bodies, i, t)
    if (self%cross_mode == CROSS_SPECULATE .and. .not. bodies%fixed(i)) then
      if (i > self%n_owned .or. self%zone_sides_of(i) /= 0) call log_change(self, flight, i, t)
    end if
  end subroutine new_trajectory

  !> Row i's new trajectory from t into the change log (see n_change_log).
  subroutine log_change(self, flight, i, t)
    type(event_loop_t), intent(inout) :: self
    type(free_flight_t), intent(in) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    integer, allocatable :: rows(:)
    real(dp), allocatable :: times(:)
    integer(i8), allocatable :: words(:, :)
    integer :: n
    n = self%n_change_log
    if (.not. allocated(self%change_log_row)) then
      allocate (self%change_log_row(64), self%change_log_time(64), self%change_log_words(flight%anchor_words(), 64))
    else if (n == size(self%change_log_row)) then
      allocate (rows(2*n), times(2*n), words(size(self%change_log_words, 1), 2*n))
      rows(1:n) = self%change_log_row(1:n)
      times(1:n) = self%change_log_time(1:n)
      words(:, 1:n) = self%change_log_words(:, 1:n)
      call move_alloc(rows, self%change_log_row)
      call move_alloc(times, self%change_log_time)
      call move_alloc(words, self%change_log_words)
    end if
    n = n + 1
    self%change_log_row(n) = i
    self%change_log_time(n) = t
    call flight%record_of(i, self%change_log_words(:, n))
    self%n_change_log = n
  end subroutine log_change

  !> Body i's trajectory changed at t (its state is that at t): a new version, counted.
  subroutine count_change(self, i, t)
    type(event_loop_t), intent(inout) :: self
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    call touch_row(self, i)
    self%state_time(i) = t
    self%version(i) = self%version(i) + 1
    self%changes(i) = self%changes(i) + 1
    self%stats%trajectory_changes = self%stats%trajectory_changes + 1
  end subroutine count_change

  !> lo, hi grown by the box of body i's centre over [its anchor time, t] on its present
  !> flight (a parabola: its ends and, per axis, its turning point) [m].
  subroutine sweep_segment(self, flight, i, t, lo, hi)
    type(event_loop_t), intent(in) :: self
    type(free_flight_t), intent(in) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    real(dp), intent(inout) :: lo(3), hi(3)
    real(dp) :: a(3), tau, s, x
    integer :: k
    a = flight%acceleration(i, self%gravity)
    tau = max(t - flight%t0(i), 0.0_dp)
    do k = 1, 3
      x = flight%x0(k, i) + flight%v0(k, i)*tau + 0.5_dp*a(k)*tau*tau
      lo(k) = min(lo(k), flight%x0(k, i), x)
      hi(k) = max(hi(k), flight%x0(k, i), x)
      if (a(k) /= 0.0_dp) then
        s = -flight%v0(k, i)/a(k)
        if (s > 0.0_dp .and. s < tau) then
          x = flight%x0(k, i) + flight%v0(k, i)*s + 0.5_dp*a(k)*s*s
          lo(k) = min(lo(k), x)
          hi(k) = max(hi(k), x)
        end if
      end if
    end do
    ! (round-off of the evaluation: a relative 1e-12 and an absolute 1e-12 m)
    lo = lo - 1.0e-12_dp*(1.0_dp + abs(lo))
    hi = hi + 1.0e-12_dp*(1.0_dp + abs(hi))
  end subroutine sweep_segment

  !> While a window's save journals (row_journal): body i's per-body row is about to change;
  !> the first time since the save, it is kept as it is now.
  subroutine touch_row(self, i)
    type(event_loop_t), intent(inout) :: self
    integer, intent(in) :: i
    integer :: m
    integer(i8), parameter :: mold = 0_i8
    if (.not. allocated(self%row_journal)) return
    if (.not. self%row_journal%active) return
    m = self%row_journal%keep(i)
    if (m == 0) return
    associate (w => self%row_journal%words(:, m))
      w(1) = self%version(i)
      w(2) = self%changes(i)
      w(3) = transfer(self%state_time(i), mold)
      w(4) = transfer(self%expiry(i), mold)
      w(5:7) = transfer(self%region_x(:, i), mold, 3)
      w(8) = self%island_of(i)
      w(9) = transfer(self%released_at(i), mold)
      w(10) = transfer(far_future, mold)
      w(11:16) = 0
      if (allocated(self%first_change)) then
        if (i <= size(self%first_change)) w(10) = transfer(self%first_change(i), mold)
      end if
      if (allocated(self%path_lo)) then
        if (i <= size(self%path_lo, 2)) then
          w(11:13) = transfer(self%path_lo(:, i), mold, 3)
          w(14:16) = transfer(self%path_hi(:, i), mold, 3)
        end if
      end if
    end associate
  end subroutine touch_row

  !> The rows kept since the save back as they were; the scratch marks cleared (their stamp
  !> went back with the copy). The journal goes on from there.
  subroutine roll_back_rows(self)
    type(event_loop_t), intent(inout) :: self
    integer :: m, i
    if (.not. allocated(self%row_journal)) return
    do m = 1, self%row_journal%n
      i = self%row_journal%ids(m)
      associate (w => self%row_journal%words(:, m))
        self%version(i) = w(1)
        self%changes(i) = w(2)
        self%state_time(i) = transfer(w(3), 1.0_dp)
        self%expiry(i) = transfer(w(4), 1.0_dp)
        self%region_x(:, i) = transfer(w(5:7), self%region_x(:, i))
        self%island_of(i) = int(w(8))
        self%released_at(i) = transfer(w(9), 1.0_dp)
        if (allocated(self%first_change)) then
          if (i <= size(self%first_change)) self%first_change(i) = transfer(w(10), 1.0_dp)
        end if
        if (allocated(self%path_lo)) then
          if (i <= size(self%path_lo, 2)) then
            self%path_lo(:, i) = transfer(w(11:13), self%path_lo(:, i))
            self%path_hi(:, i) = transfer(w(14:16), self%path_hi(:, i))
          end if
        end if
      end associate
    end do
    call self%row_journal%clear()
    self%mark = 0
    self%pair_mark = 0
    self%stamp = 0
  end subroutine roll_back_rows

  !> The per-body rows and scratch marks of `from` moved to `to` (both ways: a holder).
  subroutine move_rows(from, to)
    type(event_loop_t), intent(inout) :: from, to
    call move_alloc(from%version, to%version)
    call move_alloc(from%changes, to%changes)
    call move_alloc(from%state_time, to%state_time)
    call move_alloc(from%expiry, to%expiry)
    call move_alloc(from%region_x, to%region_x)
    call move_alloc(from%island_of, to%island_of)
    call move_alloc(from%released_at, to%released_at)
    call move_alloc(from%first_change, to%first_change)
    call move_alloc(from%path_lo, to%path_lo)
    call move_alloc(from%path_hi, to%path_hi)
    call move_alloc(from%mark, to%mark)
    call move_alloc(from%pair_mark, to%pair_mark)
    if (allocated(from%row_journal)) call move_alloc(from%row_journal, to%row_journal)
  end subroutine move_rows

  !> A cross-rank window's save (restoring false: dst, the saved copy, from src, the live
  !> loop) and restore (restoring true: dst, the live loop, from src, the saved copy). What
  !> is large and changes little in a window is not copied but kept by undo journals that the
  !> save starts in the live loop and the restore rolls back: the pair store (slots,
  !> certificates, lists: 43 MB for 50,000 spheres), the pair and body queues, and the cell
  !> grid's box table (keys, slots in use, lists: a 4-million-slot table for 50,000 spheres;
  !> its restore takes the bodies placed since the save out of the live table and puts them
  !> back at their restored box ranges, cell_grid restore_prepare, restore_finish, and with
  !> them their rows), and the loop's per-body rows (touch_row, roll_back_rows; the scratch
  !> marks are cleared instead). Every other component is copied (intrinsic assignment). The
  !> saved copy holds no pairs, queues or rows: it is only ever restored from. Journals stop
  !> at the window's end (stop_journal).
  subroutine copy_loop(dst, src, restoring)
    type(event_loop_t), intent(inout) :: dst
    type(event_loop_t), intent(inout) :: src
    logical, intent(in) :: restoring
    type(cell_lists_t) :: src_lists, dst_lists
    type(pair_store_t), allocatable :: kept_pairs
    type(event_queue_t), allocatable :: kept_pair_queue, kept_body_queue
    type(event_loop_t) :: rows_holder
    if (restoring) then
      call dst%cells%restore_prepare()
      call move_alloc(dst%pairs, kept_pairs)
      call move_alloc(dst%pair_queue, kept_pair_queue)
      call move_alloc(dst%body_queue, kept_body_queue)
      call move_rows(dst, rows_holder)
    else
      call src%cells%start_journal()
      if (.not. allocated(src%row_journal)) allocate (src%row_journal)
      if (allocated(src%version)) call src%row_journal%start(size(src%version), LOOP_ROW_WORDS)
      call move_rows(src, rows_holder)
      call move_alloc(src%pairs, kept_pairs)
      call move_alloc(src%pair_queue, kept_pair_queue)
      call move_alloc(src%body_queue, kept_body_queue)
    end if
    call src%cells%swap_table(src_lists)
    call dst%cells%swap_table(dst_lists)
    dst = src
    call src%cells%swap_table(src_lists)
    call dst%cells%swap_table(dst_lists)
    if (restoring) then
      call move_rows(rows_holder, dst)
      call roll_back_rows(dst)
      call move_alloc(kept_pairs, dst%pairs)
      call move_alloc(kept_pair_queue, dst%pair_queue)
      call move_alloc(kept_body_queue, dst%body_queue)
      call dst%cells%restore_finish()
      call dst%pairs%roll_back()
      call dst%pair_queue%roll_back()
      call dst%body_queue%roll_back()
    else
      call move_rows(rows_holder, src)
      call move_alloc(kept_pairs, src%pairs)
      call move_alloc(kept_pair_queue, src%pair_queue)
      call move_alloc(kept_body_queue, src%body_queue)
      call src%pairs%start_journal()
      call src%pair_queue%start_journal()
      call src%body_queue%start_journal()
    end if
  end subroutine copy_loop

  !> A cross-rank window ends: the undo journals its save started stop.
  subroutine loop_stop_journal(self)
    class(event_loop_t), intent(inout) :: self
    call self%cells%stop_journal()
    if (allocated(self%row_journal)) call self%row_journal%stop()
    if (allocated(self%pairs)) call self%pairs%stop_journal()
    if (allocated(self%pair_queue)) call self%pair_queue%stop_journal()
    if (allocated(self%body_queue)) call self%body_queue%stop_journal()
  end subroutine loop_stop_journal

  !> The earliest box crossing now in the queue of an owned moving body that, on the body's
  !> present trajectory, will find it outside what the halo covers (halo_left: a STOP_HALO
  !> then) (far_future if none) [s]: a time every rank's speculative run can end just
  !> before, so that a window ending at a halo stop needs no repetition when nothing comes
  !> first. A prediction only: a body whose trajectory
  !> changes before its crossing makes it void (the window then ends there with nothing to
  !> do), and a halo stop at a placement by an impact is found as before (by the run).
  !> The centre at the crossing is evaluated as flight%evaluate evaluates it.
  real(dp) function loop_queued_halo_time(self, bodies, flight) result(t)
    class(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    integer :: i
    real(dp) :: t_c, tau, a(3), x(3), reach
    t = far_future
    ! A body's centre at its crossing is within the margin of where it was placed
    ! (schedule_crossing's bound): one placed deeper than that inside the watched box, and
    ! held by no neighbour, cannot be outside what the halo covers then. (A box more for the
    ! round-off: the scan of every owned body's queued crossing was 2% of a two-rank run.)
    reach = self%margin + self%cells%h
    do i = 1, self%n_owned
      if (bodies%fixed(i) .or. .not. flight%is_anchored(i)) cycle
      if (self%zone_sides_of(i) == 0) then
        if (all(self%region_x(:, i) - reach > self%watch_lo) .and. all(self%region_x(:, i) + reach < self%watch_hi)) &
          cycle
      end if
      t_c = self%body_queue%time_of(i)
      if (t_c >= t) cycle
      tau = t_c - flight%t0(i)
      a = flight%acceleration(i, self%gravity)
      x = flight%x0(:, i) + flight%v0(:, i)*tau + (0.5_dp*tau*tau)*a
      if (halo_left_at(self, x, i)) t = t_c
    end do
  end function loop_queued_halo_time

  !> The swept boxes (path_lo, path_hi) of the owned rows that changed, closed at t (the end
  !> of the run): their last segment added.
  subroutine loop_close_paths(self, bodies, flight, t)
    class(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    real(dp), intent(in) :: t
    integer :: i
    if (.not. allocated(self%path_lo)) return
    do i = 1, min(self%n_owned, size(self%path_lo, 2))
      if (bodies%fixed(i) .or. self%first_change(i) >= far_future) cycle
      call touch_row(self, i)
      call sweep_segment(self, flight, i, t, self%path_lo(:, i), self%path_hi(:, i))
    end do
  end subroutine loop_close_paths

  !> The loop's grid for n bodies, with a dense block (cell_grid) over where the moving
  !> bodies are now, their regions grown by dense_rings boxes (a rank's ghosts arrive within
  !> two rings of bricks of about three grid boxes), if it has at most dense_per_body boxes
  !> a body: a gas at 5% solid fraction takes about 17 a body on one rank and 20 on each of
  !> two; a scene spread thinly (or a single body) keeps the hash table alone.
  subroutine init_cells(self, bodies, shapes, box_size, n, err)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    real(dp), intent(in) :: box_size
    integer, intent(in) :: n
    type(error_t), intent(inout) :: err
    integer, parameter :: dense_rings = 8, dense_per_body = 32
    real(dp) :: lower(3), upper(3), grow
    integer :: i, moving
    lower = huge(1.0_dp)
    upper = -huge(1.0_dp)
    moving = 0
    do i = 1, n
      if (bodies%fixed(i)) cycle
      moving = moving + 1
      grow = shapes%shapes(bodies%shape_id(i))%bounding_radius + 0.5_dp*self%band + self%margin
      lower = min(lower, bodies%x(:, i) - grow)
      upper = max(upper, bodies%x(:, i) + grow)
    end do
    if (moving < 2) then
      call self%cells%init(box_size, n, err)
      return
    end if
    lower = lower - dense_rings*box_size
    upper = upper + dense_rings*box_size
    call self%cells%init(box_size, n, err, dense_lower=lower, dense_upper=upper, &
                         max_dense=int(min(int(dense_per_body, i8)*n + 4096_i8, int(huge(0)/8, i8))))
  end subroutine init_cells

  !> Body i enters the grid with its bounding sphere's box, grown by the margin (moving
  !> bodies) and half the band, around where it is now.
  subroutine place(self, bodies, shapes, i, err)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    integer, intent(in) :: i
    type(error_t), intent(inout) :: err
    real(dp) :: grow
    grow = shapes%shapes(bodies%shape_id(i))%bounding_radius + 0.5_dp*self%band
    if (.not. bodies%fixed(i)) grow = grow + self%margin
    call touch_row(self, i)
    self%region_x(:, i) = bodies%x(:, i)
    call self%cells%place(i, bodies%x(:, i) - grow, bodies%x(:, i) + grow, err)
    if (err%failed()) call err%prefix('body '//str(bodies%gid(i))//': ')
    ! (every placement, not only box crossings: an impact that moves a body's region is one
    ! too, and a body hit every quarter box would otherwise never be looked at)
    if (self%cross_mode /= CROSS_OFF .and. i <= self%n_owned .and. .not. bodies%fixed(i)) then
      if (halo_left(self, bodies, i)) then
        self%halo_seen = .true.
        if (self%zone_sides_of(i) /= 0) then
          if (any(bodies%x(:, i) < self%brick_lo) .or. any(bodies%x(:, i) > self%brick_hi)) self%halo_exit_seen = .true.
        end if
        if (self%cross_mode == CROSS_SPECULATE .and. self%stop_kind == STOP_NONE) then
          self%stop_kind = STOP_HALO
          self%stop_time = self%time
        end if
      end if
    end if
  end subroutine place

  !> When body i (at t) will have used up its margin on its present trajectory.
  subroutine schedule_crossing(self, bodies, flight, i, t)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    type(closing_bound_t) :: travel
    real(dp) :: room, dt
    if (bodies%fixed(i)) then
      call self%body_queue%remove(i)
      return
    end if
    room = self%margin - norm2(bodies%x(:, i) - self%region_x(:, i))
    travel%rate = norm2(bodies%v(:, i))
    travel%acceleration = norm2(flight%acceleration(i, self%gravity))
    dt = 0.0_dp
    if (room > 0.0_dp) dt = time_to_close(travel, room)
    if (t + dt >= far_future) then
      call self%body_queue%remove(i)
    else
      call self%body_queue%set(i, t + dt, bodies%gid(i), 0_i8)
    end if
  end subroutine schedule_crossing

  !> Body i has used up its margin: placed again where it is, its new candidate pairs made
  !> and certified, the pairs whose regions no longer overlap dropped.
  subroutine crossing_event(self, stage, bodies, shapes, flight, i, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    self%stats%crossings = self%stats%crossings + 1
    call sync(self, bodies, flight, i, t)
    call replace(self, stage, bodies, shapes, flight, i, t, err)
    if (err%failed()) return
    call schedule_crossing(self, bodies, flight, i, t)
  end subroutine crossing_event

  !> Places body i again (at t) and brings its pairs up to date with its new region.
  subroutine replace(self, stage, bodies, shapes, flight, i, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer :: slot, next_slot, j, k, n_found
    call place(self, bodies, shapes, i, err)
    if (err%failed()) return
    ! pairs whose regions no longer overlap cannot come within the band before one of the
    ! two is placed again
    slot = self%pairs%head(i)
    do while (slot > 0)
      next_slot = self%pairs%next_of(slot, i)
      j = self%pairs%partner(slot, i)
      if (.not. self%cells%overlaps(i, j)) then
        call self%pair_queue%remove(slot)
        call self%pairs%remove(slot)
      end if
      slot = next_slot
    end do
    call self%cells%query(i, self%found, n_found, bodies%n_owned + bodies%n_ghost)
    do k = 1, n_found
      j = self%found(k)
      if (.not. held_pair(self, bodies, i, j)) cycle
      if (self%pairs%find(i, j) > 0) cycle
      slot = self%pairs%add(i, j, bodies%gid(i), bodies%gid(j))
      call ensure_pair_marks(self)
      call certify(self, stage, bodies, shapes, flight, slot, t, err)
      if (err%failed()) return
    end do
  end subroutine replace

  subroutine ensure_pair_marks(self)
    type(event_loop_t), intent(inout) :: self
    integer, allocatable :: grown(:)
    if (size(self%pair_mark) >= self%pairs%n_slots) return
    allocate (grown(max(2*size(self%pair_mark), self%pairs%n_slots, 64)))
    grown = 0
    grown(1:size(self%pair_mark)) = self%pair_mark
    call move_alloc(grown, self%pair_mark)
  end subroutine ensure_pair_marks

  integer function next_stamp(self) result(stamp)
    type(event_loop_t), intent(inout) :: self
    if (self%stamp == huge(self%stamp)) then
      self%mark = 0
      self%pair_mark = 0
      self%stamp = 0
    end if
    self%stamp = self%stamp + 1
    stamp = self%stamp
  end function next_stamp

  ! ---------------------------------------------------------------------------------------
  ! certificates

  !> How far bodies a and b can close on each other over h [m], from their relative motion:
  !> (|v_a - v_b| + Omega_a R_a + Omega_b R_b) h, and gravity's impulse for the step where
  !> only one of them moves (the contact pass gives it to every body it holds) g h^2. A
  !> speculative contact of the pass is active only if its own feature gap above the target
  !> plus tolerance closes by more than this in the step, so a pair further apart than
  !> this cannot be held by the pass; bodies falling side by side are not within reach of
  !> each other however fast they fall.
  real(dp) function pass_closing(self, shapes, bodies, a, b, h) result(closing)
    type(event_loop_t), intent(in) :: self
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: a, b
    real(dp), intent(in) :: h
    real(dp) :: va(3), vb(3)
    va = 0.0_dp
    vb = 0.0_dp
    if (.not. bodies%fixed(a)) va = bodies%v(:, a)
    if (.not. bodies%fixed(b)) vb = bodies%v(:, b)
    closing = (norm2(va - vb) + turning_reach(shapes, bodies, a) + turning_reach(shapes, bodies, b))*h
    if (bodies%fixed(a) .neqv. bodies%fixed(b)) closing = closing + norm2(self%gravity)*h*h
  end function pass_closing

  !> A lower bound on the gap of a and b (at their present states) from bounding volumes:
  !> their bounding spheres, and, against a static body, the moving one's sphere against
  !> the static one's box. far_time: how long it stays above `above` [s] (translation only:
  !> the bounding sphere does not turn, and a static box does not move).
  subroutine far_bound(self, shapes, bodies, flight, a, b, above, lb, far_time)
    type(event_loop_t), intent(in) :: self
    type(shape_library_t), intent(in) :: shapes
    type(bodies_t), intent(in) :: bodies
    type(free_flight_t), intent(in) :: flight
    integer, intent(in) :: a, b
    real(dp), intent(in) :: above
    real(dp), intent(out) :: lb, far_time
    type(closing_bound_t) :: bound
    real(dp) :: d(3), dist, n(3), lb_box, v(3), acc(3)
    integer :: mover, wall
    associate (sa => shapes%shapes(bodies%shape_id(a)), sb => shapes%shapes(bodies%shape_id(b)))
      d = bodies%x(:, b) - bodies%x(:, a)
      dist = norm2(d)
      lb = dist - sa%bounding_radius - sb%bounding_radius
      far_time = 0.0_dp
      if (lb > above .and. dist > 0.0_dp) then
        ! along the line of centres: the centre distance is at least its projection on it
        n = d/dist
        bound%rate = dot_product(n, velocity(a) - velocity(b))
        bound%acceleration = dot_product(n, accel(a) - accel(b))
        far_time = time_to_close(bound, lb - above)
      end if
      if (bodies%fixed(a) .neqv. bodies%fixed(b)) then
        if (bodies%fixed(a)) then
          wall = a
          mover = b
        else
          wall = b
          mover = a
        end if
        associate (sw => shapes%shapes(bodies%shape_id(wall)), sm => shapes%shapes(bodies%shape_id(mover)))
          lb_box = point_box_gap(bodies%x(:, mover), bodies%x(:, wall), bodies%q(:, wall), sw%aabb_lower, &
                                 sw%aabb_upper) - sm%bounding_radius
        end associate
        if (lb_box > lb) lb = lb_box
        if (lb_box > above) then
          ! the distance from a point to a box is 1-Lipschitz in the point
          v = velocity(mover)
          acc = accel(mover)
          bound%rate = norm2(v)
          bound%acceleration = norm2(acc)
          far_time = max(far_time, time_to_close(bound, lb_box - above))
        end if
      end if
    end associate
  contains
    function velocity(k) result(vk)
      integer, intent(in) :: k
      real(dp) :: vk(3)
      vk = 0.0_dp
      if (.not. bodies%fixed(k)) vk = bodies%v(:, k)
    end function velocity
    function accel(k) result(ak)
      integer, intent(in) :: k
      real(dp) :: ak(3)
      ak = 0.0_dp
      if (.not. bodies%fixed(k)) ak = flight%acceleration(k, self%gravity)
    end function accel
  end subroutine far_bound

  !> The certificate of pair slot from time t (both bodies evaluated there): when it must
  !> be looked at again, and what happens then. Far pairs: from bounding volumes, until they
  !> could come within `near`. Free inelastic pairs (with contact passes): until they could
  !> come within reach of the contact pass (band + one step's travel), when they take an
  !> island step (ACTION_ENTER). Otherwise the pair's time of contact by conservative
  !> advancement (collision_stage%advance_candidate, as the global loop advances it) up to
  !> the time either trajectory ends: an impact, or a time to look again.
  recursive subroutine certify(self, stage, bodies, shapes, flight, slot, t, err, enter_now, known)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: slot
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    logical, intent(out), optional :: enter_now   !< the pair is within reach of a pass now
    !> the store's gap and normal are those at t (an island step measured them): no query
    logical, intent(in), optional :: known
    type(advancement_result_t) :: res
    real(dp) :: horizon, lb, dt, gap, normal(3), d_enter, due
    integer :: a, b
    type(closing_bound_t) :: bound
    logical :: use_known, lower_only
    if (present(enter_now)) enter_now = .false.
    a = self%pairs%a(slot)
    b = self%pairs%b(slot)
    self%stats%certificates = self%stats%certificates + 1
    call self%pairs%touch(slot)
    self%pairs%stamp(:, slot) = [self%version(a), self%version(b)]
    self%pairs%t_query(slot) = t
    if (bodies%fixed(a) .and. bodies%fixed(b)) then
      call set_action(self, bodies, slot, ACTION_NONE, far_future)
      return
    end if
    call sync(self, bodies, flight, a, t)
    call sync(self, bodies, flight, b, t)
    horizon = min(self%expiry(a), self%expiry(b))
    call far_bound(self, shapes, bodies, flight, a, b, 0.5_dp*self%near, lb, dt)
    use_known = .false.
    if (present(known)) use_known = known .and. .not. self%pairs%far(slot)
    if (lb > self%near .and. .not. use_known) then
      self%stats%far_certificates = self%stats%far_certificates + 1
      self%pairs%far(slot) = .true.
      self%pairs%gap(slot) = lb
      ! (certified up to where a trajectory ends: the island step there certifies it again)
      if (t + dt >= horizon) then
        call set_action(self, bodies, slot, ACTION_NONE, far_future, until=horizon)
      else
        call set_action(self, bodies, slot, ACTION_QUERY, t + dt)
      end if
      return
    end if
    lower_only = .false.
    if (use_known) then
      gap = self%pairs%gap(slot)
      normal = self%pairs%normal(:, slot)
    else
      ! Two small convex meshes that no contact pass will take up: GJK's lower bound and its
      ! direction are all the advancement below needs while they are above the band (its
      ! iterates reach the exact query there); the pair is then stored as far (its gap a
      ! lower bound only), which is what every reader of a far pair expects.
      if (convex_pair(shapes, bodies, a, b) .and. .not. self%pairs%in_pass(slot) .and. &
          self%island_of(a) == 0 .and. self%island_of(b) == 0) then
        if (stage%materials%pair_restitution(bodies%group_id(a), bodies%group_id(b)) > 0.0_dp .or. &
            .not. self%use_pass) then
          call convex_pair_bound(shapes, bodies, a, b, bodies%x(:, a), bodies%q(:, a), bodies%x(:, b), &
                                 bodies%q(:, b), gap, normal, lower_only)
          if (lower_only) lower_only = gap > stage%target + stage%tolerance
          if (lower_only) stage%stats%convex_bounds = stage%stats%convex_bounds + 1
        end if
      end if
      if (.not. lower_only) then
        call stage%memo%pair_gap(shapes, bodies, a, b, bodies%x(:, a), bodies%q(:, a), bodies%x(:, b), &
                                 bodies%q(:, b), gap, normal)
        stage%stats%pair_tests = stage%stats%pair_tests + 1
        stage%stats%min_separation = min(stage%stats%min_separation, gap)
      end if
    end if
    self%pairs%far(slot) = lower_only
    self%pairs%gap(slot) = gap
    self%pairs%normal(:, slot) = normal
    ! a free inelastic pair approaching the reach of a contact pass: an island step there
    if (self%use_pass .and. self%island_of(a) == 0 .and. self%island_of(b) == 0 .and. .not. self%pairs%in_pass(slot)) then
      if (stage%materials%pair_restitution(bodies%group_id(a), bodies%group_id(b)) <= 0.0_dp) then
        ! (two steps ahead: a pair that waits for an island's next step is still within reach then)
        d_enter = stage%target + stage%tolerance + pass_closing(self, shapes, bodies, a, b, 2.0_dp*self%dt_max)
        ! ... unless an island step at this very time has just let one of them go: that step
        ! saw the pair (its closure measures every pair of its members) and its pass does not
        ! hold it within the step, so entering it now would only take the same step again.
        ! Taken anyway, two such pairs near one island can take turns for ever at one time
        ! (each step cuts the island, keeps its own seeds and lets the other pair's body go:
        ! the 200 L-prism pile stalled so at t = 0.6765 s on an AVX-512 machine, whose libm
        ! gave other last bits). Such a pair is advanced instead, as an elastic one is: safe,
        ! and its next certificate, at a later time, may enter it.
        if (gap <= d_enter .and. self%released_at(a) /= t .and. self%released_at(b) /= t) then
          if (t >= self%t_hard) then
            ! at the next checkpoint or the end: the rebuild there takes it up
            call set_action(self, bodies, slot, ACTION_NONE, far_future, until=self%t_hard)
            return
          end if
          if (present(enter_now)) enter_now = .true.
          call set_action(self, bodies, slot, ACTION_ENTER, t)
          return
        end if
        ! Due when the bound may bring it to the reach of one step, not two: the pair is
        ! then certainly within d_enter or has not approached as fast as the bound allows,
        ! and every certificate moves time on by a finite part of the slack (aiming at
        ! d_enter itself, a loose bound would approach it in ever smaller steps).
        if (gap > d_enter) then
          bound = enter_bound(normal)
          due = t + time_to_close(bound, gap - (stage%target + stage%tolerance + &
                                                pass_closing(self, shapes, bodies, a, b, self%dt_max)))
          if (due < horizon) then
            call set_action(self, bodies, slot, ACTION_ENTER, due)
          else
            call set_action(self, bodies, slot, ACTION_NONE, far_future, until=horizon)
          end if
          return
        end if
      end if
    end if
    ! one pair in the stage's table, as the global loop advances it
    stage%pairs(:, 1) = [a, b]
    stage%pair_gap0(1) = gap
    stage%pair_normal(:, 1) = normal
    stage%pair_far(1) = .false.
    stage%pair_in_pass(1) = self%pairs%in_pass(slot)
    ! (advanced at most lookahead_steps dt_max ahead: a turning pair's bound always closes,
    ! and poses far in the future are neither needed nor accurate)
    horizon = min(horizon, t + lookahead_steps*self%dt_max)
    call stage%advance_candidate(bodies, shapes, flight, self%gravity, self%config, t, 1, horizon - t, &
                                 queries_per_certificate, res)
    if (res%capped) stage%stats%capped = stage%stats%capped + 1
    if (res%contact .or. (res%capped .and. res%time == 0.0_dp)) then
      due = t + res%time
      ! (the canonical time itself where t + res%time rounds to a neighbour of it: the same
      ! time from any certificate's start, so on any rank and after any window's start)
      if (res%contact .and. abs(res%t_absolute - due) <= 4.0_dp*spacing(due)) due = res%t_absolute
      call set_action(self, bodies, slot, ACTION_IMPACT, due)
    else if (t + res%time >= min(self%expiry(a), self%expiry(b))) then
      ! certified up to where a trajectory ends (the island step there certifies it again)
      call set_action(self, bodies, slot, ACTION_NONE, far_future, until=min(self%expiry(a), self%expiry(b)))
    else
      call set_action(self, bodies, slot, ACTION_QUERY, t + res%time)
    end if
  contains
    !> How fast the pair can close towards the pass's reach (the first-order bound).
    function enter_bound(nrm) result(cb)
      real(dp), intent(in) :: nrm(3)
      type(closing_bound_t) :: cb
      real(dp) :: va(3), vb(3), aa(3), ab(3), turn
      va = 0.0_dp; vb = 0.0_dp; aa = 0.0_dp; ab = 0.0_dp
      if (.not. bodies%fixed(a)) then
        va = bodies%v(:, a); aa = flight%acceleration(a, self%gravity)
      end if
      if (.not. bodies%fixed(b)) then
        vb = bodies%v(:, b); ab = flight%acceleration(b, self%gravity)
      end if
      turn = turning_reach(shapes, bodies, a) + turning_reach(shapes, bodies, b)
      if (shapes%shapes(bodies%shape_id(a))%convex .and. shapes%shapes(bodies%shape_id(b))%convex) then
        cb%rate = dot_product(nrm, va - vb) + turn
        cb%acceleration = dot_product(nrm, aa - ab)
      else
        cb%rate = norm2(va - vb) + turn
        cb%acceleration = norm2(aa - ab)
      end if
    end function enter_bound
  end subroutine certify

  !> until [s]: how far the certificate reaches when that is not due (ACTION_NONE: to where
  !> a trajectory ends; default far_future), kept for the audit.
  subroutine set_action(self, bodies, slot, action, due, until)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: slot, action
    real(dp), intent(in) :: due
    real(dp), intent(in), optional :: until
    if (action /= ACTION_NONE) then
      self%pairs%certified_until(slot) = due
    else if (present(until)) then
      self%pairs%certified_until(slot) = until
    else
      self%pairs%certified_until(slot) = far_future
    end if
    self%pairs%action(slot) = action
    self%pairs%t_due(slot) = due
    if (action == ACTION_NONE) then
      call self%pair_queue%remove(slot)
    else
      call self%pair_queue%set(slot, due, bodies%gid(self%pairs%a(slot)), bodies%gid(self%pairs%b(slot)))
    end if
  end subroutine set_action

  !> Every pair of the bodies listed certified again at t (their trajectories changed).
  !> skip, when present: pairs whose pair_mark is this stamp are left out (just certified).
  subroutine certify_pairs_of(self, stage, bodies, shapes, flight, list, t, err, skip)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: list(:)
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer, intent(in), optional :: skip
    integer :: m, slot, stamp, skip_stamp
    integer, allocatable :: slots(:)
    integer :: n_slots
    call ensure_pair_marks(self)
    skip_stamp = -1
    if (present(skip)) skip_stamp = skip
    stamp = next_stamp(self)
    allocate (slots(16))
    n_slots = 0
    do m = 1, size(list)
      slot = self%pairs%head(list(m))
      do while (slot > 0)
        if (self%pair_mark(slot) /= stamp .and. self%pair_mark(slot) /= skip_stamp) then
          self%pair_mark(slot) = stamp
          call push(slots, n_slots, slot)
        end if
        slot = self%pairs%next_of(slot, list(m))
      end do
    end do
    call sort_slots(self, bodies, slots, n_slots)
    do m = 1, n_slots
      call certify(self, stage, bodies, shapes, flight, slots(m), t, err)
      if (err%failed()) return
    end do
  end subroutine certify_pairs_of

  !> Pair slots in increasing (gid a, gid b): the order of work never depends on storage.
  !> flags, when present, are reordered with them.
  subroutine sort_slots(self, bodies, slots, n, flags)
    type(event_loop_t), intent(in) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(inout) :: slots(:)
    integer, intent(in) :: n
    logical, intent(inout), optional :: flags(:)
    integer(i8), allocatable :: keys(:, :)
    integer, allocatable :: order(:)
    integer :: k
    if (n < 2) return
    allocate (keys(2, n))
    do k = 1, n
      keys(:, k) = [bodies%gid(self%pairs%a(slots(k))), bodies%gid(self%pairs%b(slots(k)))]
    end do
    call sort_index_keys(keys, order)
    slots(1:n) = slots(order)
    if (present(flags)) flags(1:n) = flags(order)
  end subroutine sort_slots

  ! ---------------------------------------------------------------------------------------
  ! events

  subroutine pair_event(self, stage, bodies, shapes, flight, slot, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: slot
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    logical :: enter_now
    integer :: seeds(2), n_seeds
    ! (a certificate is certified again whenever a version changes, so a popped one is
    ! current; the stamps say so, and a stale one is simply certified again)
    if (.not. self%pairs%current(slot, self%version)) then
      call certify(self, stage, bodies, shapes, flight, slot, t, err)
      return
    end if
    select case (self%pairs%action(slot))
    case (ACTION_IMPACT)
      call impact(self, stage, bodies, shapes, flight, slot, t, err)
    case (ACTION_ENTER)
      call certify(self, stage, bodies, shapes, flight, slot, t, err, enter_now)
      if (err%failed() .or. .not. enter_now) return
      self%stats%enters = self%stats%enters + 1
      n_seeds = 0
      if (.not. bodies%fixed(self%pairs%a(slot))) then
        n_seeds = n_seeds + 1
        seeds(n_seeds) = self%pairs%a(slot)
      end if
      if (.not. bodies%fixed(self%pairs%b(slot))) then
        n_seeds = n_seeds + 1
        seeds(n_seeds) = self%pairs%b(slot)
      end if
      call island_step(self, stage, bodies, shapes, flight, seeds(1:n_seeds), t, .true., err)
    case default
      call certify(self, stage, bodies, shapes, flight, slot, t, err)
    end select
  end subroutine pair_event

  !> The same pair in contact again and again at one time: after max_repeated_impacts an
  !> error naming it (a run that stops with a message, never one that hangs). Known cause
  !> (docs/contact.md, "Known limits"): a pair between the settling floor and the floor plus
  !> the tolerance that its island's contact pass leaves approaching.
  subroutine check_repeated_impact(self, bodies, stage, slot, t, err)
    type(event_loop_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    type(collision_stage_t), intent(in) :: stage
    integer, intent(in) :: slot
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer, parameter :: max_repeated_impacts = 50
    integer(i8) :: pair(2)
    pair = [bodies%gid(self%pairs%a(slot)), bodies%gid(self%pairs%b(slot))]
    if (t == self%last_impact_time .and. all(pair == self%last_impact_pair)) then
      self%repeated_impacts = self%repeated_impacts + 1
    else
      self%repeated_impacts = 0
      self%last_impact_time = t
      self%last_impact_pair = pair
    end if
    if (self%repeated_impacts < max_repeated_impacts) return
    call err%set(ERR_NUMERIC, 'collision loop stalled: bodies '//str(pair(1))//' and '//str(pair(2))//' came into '// &
                 'contact '//str(max_repeated_impacts)//' times in a row at t = '//str(t)//' s (gap '// &
                 str(self%pairs%gap(slot), '(es10.3)')//' m, min_separation '//str(stage%target, '(es10.3)')// &
                 ' m): the contact pass of their island leaves them approaching (docs/contact.md, "Known limits")')
  end subroutine check_repeated_impact

  !> Pair slot reaches contact at t: its impulse group (the band contacts connected to it
  !> through moving bodies, sleeping islands it reaches woken), the steps of the islands it
  !> touches cut at t, the impulses (collision_stage%resolve, as the global loop solves an
  !> event), and the new trajectories of the bodies that changed; with contact passes, the
  !> group and the cut islands then take an island step from t.
  subroutine impact(self, stage, bodies, shapes, flight, slot, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: slot
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer, allocatable :: group(:), contact_slots(:), reseed(:), changed(:)
    integer :: n_group, n_contact, n_reseed, n_changed, k, m
    logical :: any_change, repeat, incomplete, twice
    ! (the stage's counters before an impact the other rank counts)
    type(collision_stats_t) :: stats_before
    type(impulse_stats_t) :: impulses_before
    type(pgs_stats_t) :: friction_before, residual_before
    integer :: n_log_before
    integer(i8) :: changes_before
    self%stats%impacts = self%stats%impacts + 1
    call check_repeated_impact(self, bodies, stage, slot, t, err)
    if (err%failed()) return
    ! Has this pair had an impact at this very time already? (see the island step below)
    if (t /= self%impacts_now_time) then
      self%n_impacts_now = 0
      self%impacts_now_time = t
    end if
    repeat = .false.
    if (self%n_impacts_now > 0) repeat = any(self%impacts_now(1:self%n_impacts_now) == slot)
    if (.not. repeat) call push(self%impacts_now, self%n_impacts_now, slot)
    call impulse_group(self, stage, bodies, shapes, flight, slot, t, group, n_group, contact_slots, n_contact, err, &
                       incomplete)
    if (err%failed()) return
    twice = .false.
    if (self%cross_mode == CROSS_SPECULATE .or. self%cross_mode == CROSS_RERUN) then
      ! a group reaching another rank's body: taken here as on that rank (see CROSS_OFF),
      ! if every body it may touch is held here; else the run stops (the state is the
      ! caller's to restore)
      if (any([(is_moving_ghost(self, bodies, group(k)), k=1, n_group)])) then
        if (incomplete .or. (self%cross_mode == CROSS_RERUN .and. t >= self%rerun_to)) then
          if (self%cross_mode == CROSS_RERUN .and. t < self%rerun_to) then
            call err%set(ERR_INTERNAL, 'cross-rank window: the impulse group of bodies '// &
                         str(bodies%gid(self%pairs%a(slot)))//' and '//str(bodies%gid(self%pairs%b(slot)))// &
                         ' reaches beyond the bodies held here at t = '//str(t)// &
                         ' s in a run repeated to an earlier time')
            return
          end if
          ! (queued again at t, uncounted: the caller's cross phase or next window takes it)
          self%stats%impacts = self%stats%impacts - 1
          call set_action(self, bodies, slot, ACTION_IMPACT, t)
          call stop_for_cross(self, bodies, self%pairs%a(slot), self%pairs%b(slot), group(1:n_group), t)
          return
        end if
        ! counted (impacts, the stage's counters, the event log) by the owner of the pair's
        ! deciding body only (deciding_row), so that the counts are those of one rank
        twice = deciding_row(bodies, self%pairs%a(slot), self%pairs%b(slot)) > self%n_owned
        if (twice) then
          self%stats%impacts = self%stats%impacts - 1
          stats_before = stage%stats
          impulses_before = stage%impulses
          friction_before = stage%impact_friction
          residual_before = stage%residual_pgs
          n_log_before = stage%n_log
          changes_before = self%stats%trajectory_changes
        else
          self%stats%cross_impacts = self%stats%cross_impacts + 1
        end if
      end if
    end if
    if (self%cross_mode == CROSS_PHASE .and. allocated(self%ghost_changed_at)) then
      ! a ghost its owner changed by now: this rank's copy is stale; the next window's is not
      if (any([(is_moving_ghost(self, bodies, group(k)), k=1, n_group)])) then
        if (any([(self%ghost_changed_at(group(k)) <= t, k=1, n_group)])) then
          ! left to the next window: the pair queued again at t and the phase ends here
          ! (its other events at t too: the next window takes them with fresh ghosts)
          self%deferred = self%deferred + 1
          self%stats%impacts = self%stats%impacts - 1
          call set_action(self, bodies, slot, ACTION_IMPACT, t)
          self%stop_kind = STOP_CROSS
          self%stop_time = t
          return
        end if
      end if
    end if
    ! islands touched: their steps end here, what their passes gave for the rest taken back
    allocate (reseed(16))
    n_reseed = 0
    do k = 1, n_group
      if (self%island_of(group(k)) > 0) call cut_island(self, stage, bodies, flight, self%island_of(group(k)), t, &
                                                        reseed, n_reseed)
    end do
    ! the impulses, on a table of the group's contact pairs
    call load_table(self, stage, bodies, contact_slots(1:n_contact))
    stage%n_events = 1
    if (allocated(stage%event_pairs)) deallocate (stage%event_pairs)
    allocate (stage%event_pairs(2, 1))
    stage%event_pairs(:, 1) = [self%pairs%a(slot), self%pairs%b(slot)]
    call stage%resolve(bodies, shapes, flight, 1.0_dp, 1.0_dp, err, time=t)
    if (err%failed()) return
    stage%n_events = 0
    ! new trajectories: every body released by the impulses or by a cut pass
    allocate (changed(n_group + n_reseed))
    n_changed = 0
    any_change = .false.
    do m = 1, n_group + n_reseed
      if (m <= n_group) then
        k = group(m)
      else
        k = reseed(m - n_group)
      end if
      if (bodies%fixed(k) .or. flight%is_anchored(k)) cycle
      if (m <= n_group) any_change = .true.
      call new_trajectory(self, bodies, flight, k, t)
      n_changed = n_changed + 1
      changed(n_changed) = k
    end do
    if (twice) then
      ! (the work counters stay: this rank did the work)
      stats_before%pair_tests = stage%stats%pair_tests
      stats_before%advancement_iterations = stage%stats%advancement_iterations
      stats_before%capped = stage%stats%capped
      stats_before%plane_skips = stage%stats%plane_skips
      stats_before%convex_bounds = stage%stats%convex_bounds
      stats_before%min_separation = stage%stats%min_separation
      stage%stats = stats_before
      stage%impulses = impulses_before
      stage%impact_friction = friction_before
      stage%residual_pgs = residual_before
      stage%n_log = n_log_before
      self%stats%trajectory_changes = changes_before
    end if
    if (any_change) then
      self%zero_impacts = 0
    else
      self%zero_impacts = self%zero_impacts + 1
      if (self%zero_impacts > 1000) then
        call err%set(ERR_NUMERIC, 'collision loop stalled: 1000 impacts in a row changed nothing, the last between '// &
                     'bodies '//str(bodies%gid(self%pairs%a(slot)))//' and '//str(bodies%gid(self%pairs%b(slot)))// &
                     ' at t = '//str(t)//' s')
        return
      end if
    end if
    if (self%use_pass) then
      if (repeat) then
        ! The island's pass gave the approach back that this pair's impulse took away (an
        ! unconverged solve over a large island leaves a contact between the settling floor
        ! and the floor plus the tolerance approaching slowly): this step's velocities are
        ! held to the impacts' non-approach, solved exactly after its pass (hold_pairs).
        self%stats%holds = self%stats%holds + 1
        call island_step(self, stage, bodies, shapes, flight, [group(1:n_group), reseed(1:n_reseed)], t, .true., err, &
                         hold=self%impacts_now(1:self%n_impacts_now))
      else
        call island_step(self, stage, bodies, shapes, flight, [group(1:n_group), reseed(1:n_reseed)], t, .true., err)
      end if
    else
      call settle_changed(self, stage, bodies, shapes, flight, changed(1:n_changed), t, err)
      ! the pair itself, if nothing changed (it is certified from here, not found again)
      if (.not. any_change) call certify(self, stage, bodies, shapes, flight, slot, t, err)
    end if
  end subroutine impact

  !> The impulse group of pair slot at t: the moving bodies connected to it by pairs within
  !> the contact band (group(1:n_group), sleeping islands reached woken and included) and
  !> those pairs (contact_slots(1:n_contact), by global ids).
  subroutine impulse_group(self, stage, bodies, shapes, flight, slot, t, group, n_group, contact_slots, n_contact, err, &
                           incomplete)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: slot
    real(dp), intent(in) :: t
    integer, allocatable, intent(out) :: group(:), contact_slots(:)
    integer, intent(out) :: n_group, n_contact
    type(error_t), intent(inout) :: err
    !> a ghost of the group lies where not all it may touch is held here (outside
    !> [complete_lo, complete_hi]): the group is not known here (an error in a cross phase)
    logical, intent(out) :: incomplete
    integer, allocatable :: woken(:)
    integer :: stamp, k, q, m, i, n_woken, w, n_found
    real(dp) :: gap, normal(3), lb, dt
    allocate (group(16), contact_slots(16))
    n_group = 0
    n_contact = 0
    incomplete = .false.
    call ensure_pair_marks(self)
    stamp = next_stamp(self)
    call join(self%pairs%a(slot))
    call join(self%pairs%b(slot))
    if (bodies%fixed(self%pairs%a(slot)) .and. bodies%fixed(self%pairs%b(slot))) return
    k = 0
    do while (k < n_group)
      k = k + 1
      i = group(k)
      call sync(self, bodies, flight, i, t)
      if (self%cross_mode /= CROSS_OFF .and. i > self%n_owned) then
        ! a ghost of a cross-rank impact: its pairs with every body held here (those with
        ! ghosts and fixed bodies are not kept otherwise), if all it may touch is held
        if (any(bodies%x(:, i) < self%complete_lo) .or. any(bodies%x(:, i) > self%complete_hi)) then
          incomplete = .true.
          if (self%cross_mode /= CROSS_PHASE) return
          call err%set(ERR_INTERNAL, 'cross-rank impact at t = '//str(t)//' s: the impulse group of bodies '// &
                       str(bodies%gid(self%pairs%a(slot)))//' and '//str(bodies%gid(self%pairs%b(slot)))// &
                       ' reaches body '//str(bodies%gid(i))//' too far from this rank''s brick to see all it '// &
                       'touches (impulse groups across more than one brick face are not built yet)')
          return
        end if
        call self%cells%query(i, self%found, n_found, bodies%n_owned + bodies%n_ghost)
        do w = 1, n_found
          m = self%found(w)
          if (bodies%fixed(i) .and. bodies%fixed(m)) cycle
          if (self%pairs%find(i, m) > 0) cycle
          q = self%pairs%add(i, m, bodies%gid(i), bodies%gid(m))
          if (.not. held_pair(self, bodies, i, m)) self%foreign_pairs = .true.
        end do
        call ensure_pair_marks(self)
      end if
      q = self%pairs%head(i)
      do while (q > 0)
        m = self%pairs%partner(q, i)
        if (self%pair_mark(q) /= stamp) then
          self%pair_mark(q) = stamp
          call sync(self, bodies, flight, m, t)
          call far_bound(self, shapes, bodies, flight, i, m, self%band, lb, dt)
          if (lb <= self%band .and. .not. (bodies%fixed(i) .and. bodies%fixed(m))) then
            call stage%memo%pair_gap(shapes, bodies, self%pairs%a(q), self%pairs%b(q), bodies%x(:, self%pairs%a(q)), &
                                     bodies%q(:, self%pairs%a(q)), bodies%x(:, self%pairs%b(q)), &
                                     bodies%q(:, self%pairs%b(q)), gap, normal)
            stage%stats%pair_tests = stage%stats%pair_tests + 1
            if (gap <= self%band) then
              call push(contact_slots, n_contact, q)
              if (bodies%asleep(m) .and. .not. bodies%fixed(i)) then
                ! a moving body reaches a sleeping island: it wakes, whole, and joins
                n_woken = 0
                call stage%sleep%wake_island_of(bodies, flight, m, woken, n_woken)
                do w = 1, n_woken
                  call new_trajectory(self, bodies, flight, woken(w), t)
                  call schedule_crossing(self, bodies, flight, woken(w), t)
                  call join(woken(w))
                end do
              end if
              call join(m)
            end if
          end if
        end if
        q = self%pairs%next_of(q, i)
      end do
    end do
    call sort_slots(self, bodies, contact_slots, n_contact)
    if (err%failed()) return
  contains
    subroutine join(body)
      integer, intent(in) :: body
      if (bodies%fixed(body)) return
      if (self%mark(body) == stamp) return
      self%mark(body) = stamp
      call push(group, n_group, body)
    end subroutine join
  end subroutine impulse_group

  !> Island slot's step ends at t before its time (an impact on it, or a merge): every
  !> member evaluated at t, the pass's part for the time not taken returned, the members
  !> appended to list(n_list+1:).
  subroutine cut_island(self, stage, bodies, flight, island, t, list, n_list)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: island
    real(dp), intent(in) :: t
    integer, allocatable, intent(inout) :: list(:)
    integer, intent(inout) :: n_list
    integer, allocatable :: members(:)
    integer :: k, id
    ! (island may be an element of island_of, which this changes: copied first)
    id = island
    associate (isl => self%islands%islands(id))
      members = isl%members(1:isl%n)
      self%stats%island_cuts = self%stats%island_cuts + 1
      do k = 1, size(members)
        call sync(self, bodies, flight, members(k), t)
        call touch_row(self, members(k))
        self%island_of(members(k)) = 0
        self%expiry(members(k)) = far_future
        call push(list, n_list, members(k))
      end do
      call stage%return_unused_pass(bodies, flight, t - isl%t_start, members, isl%pass_step)
    end associate
    call self%island_queue%remove(id)
    call self%islands%remove(id)
  end subroutine cut_island

  !> The island's step ends at t as planned: its members finish the step, and those still
  !> awake take the next one.
  subroutine island_end(self, stage, bodies, shapes, flight, island, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: island
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer, allocatable :: awake(:)
    integer :: n_awake
    allocate (awake(16))
    n_awake = 0
    call finish_island(self, stage, bodies, shapes, flight, island, t, awake, n_awake, err)
    if (err%failed()) return
    if (n_awake > 0) call island_step(self, stage, bodies, shapes, flight, awake(1:n_awake), t, .false., err)
  end subroutine island_end

  !> Island slot's step ends at t, its planned end: members evaluated there, the pass's
  !> unused part (a step cut by the grid) returned, sleeping; the members still awake are
  !> appended to list(n_list+1:).
  subroutine finish_island(self, stage, bodies, shapes, flight, island, t, list, n_list, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: island
    real(dp), intent(in) :: t
    integer, allocatable, intent(inout) :: list(:)
    integer, intent(inout) :: n_list
    type(error_t), intent(inout) :: err
    integer, allocatable :: members(:), band_pairs(:, :), asleep_now(:)
    integer :: k, n_asleep_now, id
    real(dp) :: step, pass_step
    id = island     ! (island may be an element of island_of, which this changes)
    associate (isl => self%islands%islands(id))
      members = isl%members(1:isl%n)
      step = isl%step
      pass_step = isl%pass_step
      band_pairs = isl%band_pairs(:, 1:isl%n_band_pairs)
    end associate
    call self%island_queue%remove(id)
    call self%islands%remove(id)
    do k = 1, size(members)
      call sync(self, bodies, flight, members(k), t)
      call touch_row(self, members(k))
      self%island_of(members(k)) = 0
      self%expiry(members(k)) = far_future
    end do
    call stage%return_unused_pass(bodies, flight, step, members, pass_step)
    call stage%sleep%update(bodies, shapes, flight, step, band_pairs, size(band_pairs, 2), members, asleep_now, &
                            n_asleep_now)
    if (n_asleep_now > 0) then
      ! asleep: static until touched
      do k = 1, n_asleep_now
        call new_trajectory(self, bodies, flight, asleep_now(k), t)
        call self%body_queue%remove(asleep_now(k))
      end do
      call certify_pairs_of(self, stage, bodies, shapes, flight, asleep_now(1:n_asleep_now), t, err)
      if (err%failed()) return
    end if
    do k = 1, size(members)
      if (.not. bodies%fixed(members(k))) call push(list, n_list, members(k))
    end do
  end subroutine finish_island

  !> One island step from T: the seeds, and every body within reach of a contact pass of
  !> theirs (transitively: the closure, bodies of other islands cutting those islands'
  !> steps, sleeping ones woken), step together over h (dt_max, the next checkpoint or the
  !> end, and one grid box of travel): distance correction, the contact pass, then islands
  !> of the bodies joined by pass pairs, each with its clock, and every pair of theirs
  !> certified over the step. keep_seeds: the seeds stay members for this step even with
  !> nothing within reach (they came here because a pair of theirs is about to be).
  !> no_wait, when present and true: islands reached are cut, never waited for.
  !> hold, when present: pair slots that had impacts at T; after the pass, the band contacts
  !> of those of them in this step approach no more (hold_pairs).
  recursive subroutine island_step(self, stage, bodies, shapes, flight, seeds, T, keep_seeds, err, no_wait, hold)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: seeds(:)
    real(dp), intent(in) :: T
    logical, intent(in) :: keep_seeds
    type(error_t), intent(inout) :: err
    logical, intent(in), optional :: no_wait
    integer, intent(in), optional :: hold(:)
    integer, allocatable :: members(:), table(:), woken(:), pass_pairs(:, :), label(:), kept(:), changed(:), &
                            in_island(:), first_of(:), by_label(:), fill(:), slot_of(:)
    logical, allocatable :: relevant(:)
    integer :: n_members, n_table, k, q, m, i, stamp, w, n_woken, n_pass, n_components, c, island, n_kept, &
               n_changed
    real(dp) :: h0, h, h2, lb, dt, gap, normal(3), reach
    logical :: low, can_wait, several, wait
    integer :: wait_for
    real(dp) :: t_wait
    self%stats%island_steps = self%stats%island_steps + 1
    if (T /= self%steps_now_time) then
      self%steps_now = 0
      self%steps_now_time = T
    end if
    self%steps_now = self%steps_now + 1
    if (self%steps_now > 100 + 4*(bodies%n_owned + bodies%n_ghost)) then
      if (size(seeds) > 0) then
        call err%set(ERR_NUMERIC, 'collision loop stalled: '//str(self%steps_now)//' island steps at t = '//str(T)// &
                     ' s without time passing, the last seeded by body '//str(bodies%gid(seeds(1)))// &
                     ' (docs/contact.md, "Known limits")')
      else
        call err%set(ERR_NUMERIC, 'collision loop stalled: '//str(self%steps_now)//' island steps at t = '//str(T)// &
                     ' s without time passing (docs/contact.md, "Known limits")')
      end if
      return
    end if
    h0 = min(self%dt_max, self%t_hard - T)
    if (h0 <= 0.0_dp) then
      ! at the next checkpoint or the end: the rebuild there steps them (certified till then)
      call settle_changed(self, stage, bodies, shapes, flight, pack(seeds, .not. bodies%fixed(seeds)), T, err)
      return
    end if
    allocate (members(16), table(16))
    n_members = 0
    n_table = 0
    ! Seeds none of which a pass holds (free bodies about to land) may wait for an island
    ! they reach instead of cutting its step.
    can_wait = .true.
    if (present(no_wait)) can_wait = .not. no_wait
    several = .false.
    do k = 1, size(seeds)
      if (.not. bodies%fixed(seeds(k))) then
        if (flight%loaded(seeds(k))) can_wait = .false.
      end if
    end do
    wait_for = 0
    ! seeds near the end of their margins are placed again first, so their pairs are complete
    ! (members that join later are placed again after the step: placing drops pairs, which
    ! must not happen while the table holds them)
    do k = 1, size(seeds)
      if (bodies%fixed(seeds(k))) cycle
      call sync(self, bodies, flight, seeds(k), T)
      if (norm2(bodies%x(:, seeds(k)) - self%region_x(:, seeds(k))) > 0.5_dp*self%margin) then
        call replace(self, stage, bodies, shapes, flight, seeds(k), T, err)
        if (err%failed()) return
      end if
    end do
    call ensure_pair_marks(self)
    stamp = next_stamp(self)
    do k = 1, size(seeds)
      call add_member(seeds(k))
      if (err%failed()) return
    end do
    h = stage%limit_step(bodies, flight, self%gravity, h0, members(1:n_members))
    ! the closure: partners within reach of a pass of a member join
    allocate (relevant(16))
    k = 0
    do while (k < n_members)
      k = k + 1
      i = members(k)
      q = self%pairs%head(i)
      do while (q > 0)
        m = self%pairs%partner(q, i)
        if (self%pair_mark(q) /= stamp) then
          self%pair_mark(q) = stamp
          call sync(self, bodies, flight, m, T)
          call push(table, n_table, q)
          if (size(relevant) < n_table) call grow_logical(relevant)
          relevant(n_table) = .false.
          ! gap at T: closest points where the bounding volumes cannot settle it
          reach = pass_closing(self, shapes, bodies, i, m, h)
          call far_bound(self, shapes, bodies, flight, i, m, self%band + reach, lb, dt)
          call self%pairs%touch(q)
          self%pairs%t_query(q) = T
          if (lb > self%band + reach .or. (bodies%fixed(i) .and. bodies%fixed(m))) then
            self%pairs%far(q) = .true.
            self%pairs%gap(q) = lb
          else
            call stage%memo%pair_gap(shapes, bodies, self%pairs%a(q), self%pairs%b(q), bodies%x(:, self%pairs%a(q)), &
                                     bodies%q(:, self%pairs%a(q)), bodies%x(:, self%pairs%b(q)), &
                                     bodies%q(:, self%pairs%b(q)), gap, normal)
            stage%stats%pair_tests = stage%stats%pair_tests + 1
            stage%stats%min_separation = min(stage%stats%min_separation, gap)
            self%pairs%far(q) = .false.
            self%pairs%gap(q) = gap
            self%pairs%normal(:, q) = normal
            low = gap < 0.75_dp*stage%target
            if (gap <= self%band .or. low) then
              relevant(n_table) = .true.
            else if (stage%materials%pair_restitution(bodies%group_id(i), bodies%group_id(m)) <= 0.0_dp) then
              relevant(n_table) = gap - (stage%target + stage%tolerance) <= reach
            end if
            ! what the pass may not hold it does not see (far), so its bodies stay apart from it
            if (.not. relevant(n_table)) self%pairs%far(q) = .true.
            if (relevant(n_table)) then
              if (bodies%asleep(m) .and. .not. bodies%fixed(i) .and. reaches(i, gap, normal)) then
                n_woken = 0
                call stage%sleep%wake_island_of(bodies, flight, m, woken, n_woken)
                do w = 1, n_woken
                  call new_trajectory(self, bodies, flight, woken(w), T)
                  call schedule_crossing(self, bodies, flight, woken(w), T)
                  call add_member(woken(w))
                end do
              end if
              if (.not. bodies%fixed(m)) then
                call add_member(m)
                if (err%failed()) return
                h = stage%limit_step(bodies, flight, self%gravity, h, [m])
              end if
            end if
          end if
        end if
        q = self%pairs%next_of(q, i)
      end do
    end do
    if (wait_for > 0) then
      ! Free bodies that reached an island wait for its next step if nothing of theirs can
      ! touch before it (checked on every pair measured above); otherwise the islands
      ! reached are cut after all, and this step taken with them.
      wait = .not. several
      t_wait = self%islands%islands(wait_for)%t_start + self%islands%islands(wait_for)%step - T
      do k = 1, n_table
        if (.not. wait) exit
        q = table(k)
        if (self%pairs%gap(q) - (stage%target + stage%tolerance) <= &
            pass_closing(self, shapes, bodies, self%pairs%a(q), self%pairs%b(q), t_wait)) wait = .false.
      end do
      if (wait) then
        call join_island(self, stage, bodies, shapes, flight, wait_for, members(1:n_members), T, err)
      else
        ! Every body gathered so far is a seed of the step taken instead, not only the first
        ! seeds: islands whose steps ended at T were finished above and their members added,
        ! and a member the second closure did not reach again would be left in no island
        ! with certificates that ran only to that island's end (a landing cube went 0.26 mm
        ! below the settling floor so, docs/benchmarks.md section 7).
        call island_step(self, stage, bodies, shapes, flight, members(1:n_members), T, keep_seeds, err, &
                         no_wait=.true., hold=hold)
      end if
      return
    end if
    self%stats%body_steps = self%stats%body_steps + n_members
    ! the table: every pair of a member, by global ids; the pass's travel bounds over h
    call sort_slots(self, bodies, table, n_table, relevant)
    call stage%reserve_table(n_table, bodies%n_owned + bodies%n_ghost)
    call load_table(self, stage, bodies, table(1:n_table))
    stage%n_pairs = n_table
    do k = 1, n_table
      do c = 1, 2
        i = stage%pairs(c, k)
        stage%turn(i) = turning_reach(shapes, bodies, i)*h
        stage%grid_margin(i) = 0.0_dp
        if (.not. bodies%fixed(i)) stage%grid_margin(i) = norm2(bodies%v(:, i))*h + &
                                                          norm2(flight%acceleration(i, self%gravity))*h*h
      end do
    end do
    call stage%correct_distances(bodies, shapes, flight)
    ! warm starts: the forces of the members' previous steps, whichever islands solved them
    stage%resting%warm_now = T
    stage%resting%warm_since = T - 1.01_dp*self%dt_max
    call stage%contact_pass(bodies, shapes, flight, h, self%gravity, err, members=members(1:n_members))
    if (err%failed()) return
    h2 = stage%limit_step(bodies, flight, self%gravity, h, members(1:n_members))
    ! what the correction and the pass found goes back to the store
    do k = 1, n_table
      q = table(k)
      call self%pairs%touch(q)
      self%pairs%in_pass(q) = stage%pair_in_pass(k)
      self%pairs%far(q) = stage%pair_far(k)
      self%pairs%gap(q) = stage%pair_gap0(k)
      self%pairs%normal(:, q) = stage%pair_normal(:, k)
    end do
    if (present(hold)) then
      call hold_pairs(self, stage, bodies, shapes, flight, hold, table(1:n_table), T, err)
      if (err%failed()) return
    end if
    ! islands: the members joined by pass pairs (members with none leave, unless kept)
    allocate (pass_pairs(2, n_table))
    n_pass = 0
    do k = 1, n_table
      if (.not. relevant(k)) cycle
      n_pass = n_pass + 1
      pass_pairs(:, n_pass) = stage%pairs(:, k)
    end do
    ! kept: the members in a pass pair, and the seeds if asked
    stamp = next_stamp(self)
    do k = 1, n_pass
      self%mark(pass_pairs(1, k)) = stamp
      self%mark(pass_pairs(2, k)) = stamp
    end do
    if (keep_seeds) then
      do k = 1, size(seeds)
        self%mark(seeds(k)) = stamp
      end do
    end if
    allocate (kept(n_members + 2*n_table))
    n_kept = 0
    do k = 1, n_members
      i = members(k)
      if (bodies%fixed(i) .or. self%mark(i) /= stamp) cycle
      n_kept = n_kept + 1
      kept(n_kept) = i
    end do
    ! (and a free partner the pass held after all, so that its load ends with a step: the
    ! pass sees only the pairs the closure found within reach, whose bodies are members, so
    ! this is a guard)
    do k = 1, n_table
      do c = 1, 2
        i = stage%pairs(c, k)
        if (bodies%fixed(i) .or. self%mark(i) == stamp) cycle
        if (self%island_of(i) /= 0 .or. flight%is_anchored(i) .or. .not. flight%loaded(i)) cycle
        self%mark(i) = stamp
        n_kept = n_kept + 1
        kept(n_kept) = i
      end do
    end do
    ! new trajectories: whatever the correction or the pass changed, and the members that
    ! leave (their loads were cleared by the pass)
    allocate (changed(n_members + 2*n_table))
    n_changed = 0
    stamp = next_stamp(self)
    do k = 1, n_table
      do c = 1, 2
        i = stage%pairs(c, k)
        if (bodies%fixed(i) .or. self%mark(i) == stamp) cycle
        self%mark(i) = stamp
        if (flight%is_anchored(i)) cycle
        call new_trajectory(self, bodies, flight, i, T)
        n_changed = n_changed + 1
        changed(n_changed) = i
      end do
    end do
    do k = 1, n_members
      i = members(k)
      if (bodies%fixed(i) .or. self%mark(i) == stamp) cycle
      self%mark(i) = stamp
      if (flight%is_anchored(i)) cycle
      call new_trajectory(self, bodies, flight, i, T)
      n_changed = n_changed + 1
      changed(n_changed) = i
    end do
    if (n_kept > 0) then
      call body_islands(kept, n_kept, pass_pairs, n_pass, label, n_components)
      ! members by component (a counting sort: stable, so each keeps the members' order)
      allocate (first_of(n_components + 1), by_label(n_kept), slot_of(n_components))
      first_of = 0
      do k = 1, n_kept
        first_of(label(k) + 1) = first_of(label(k) + 1) + 1
      end do
      first_of(1) = 1
      do c = 1, n_components
        first_of(c + 1) = first_of(c + 1) + first_of(c)
      end do
      fill = first_of(1:n_components)
      do k = 1, n_kept
        by_label(fill(label(k))) = kept(k)
        fill(label(k)) = fill(label(k)) + 1
      end do
      do c = 1, n_components
        in_island = by_label(first_of(c):first_of(c + 1) - 1)
        island = self%islands%add(in_island, T, h2, h)
        slot_of(c) = island
        do k = 1, size(in_island)
          call touch_row(self, in_island(k))
          self%island_of(in_island(k)) = island
          self%expiry(in_island(k)) = T + h2
        end do
        call self%island_queue%set(island, T + h2, bodies%gid(in_island(1)), 0_i8)
      end do
      call keep_band_pairs(self, stage, bodies, slot_of)
    end if
    ! the members it lets go (in no island now): not entered again at T (certify)
    do k = 1, n_members
      i = members(k)
      if (.not. bodies%fixed(i) .and. self%island_of(i) == 0) then
        call touch_row(self, i)
        self%released_at(i) = T
      end if
    end do
    ! every pair of a member (its gap at T measured above), and of any body whose trajectory
    ! changed, certified from T
    stamp = next_stamp(self)
    do k = 1, n_table
      self%pair_mark(table(k)) = stamp
      call certify(self, stage, bodies, shapes, flight, table(k), T, err, known=.true.)
      if (err%failed()) return
    end do
    call certify_pairs_of(self, stage, bodies, shapes, flight, changed(1:n_changed), T, err, skip=stamp)
    if (err%failed()) return
    ! crossings on the new trajectories (members changed by an impact before this step too);
    ! members near the end of their margins placed again now
    do k = 1, n_members
      i = members(k)
      if (bodies%fixed(i)) cycle
      if (norm2(bodies%x(:, i) - self%region_x(:, i)) > 0.5_dp*self%margin) then
        call replace(self, stage, bodies, shapes, flight, i, T, err)
        if (err%failed()) return
      end if
      call schedule_crossing(self, bodies, flight, i, T)
    end do
    do k = 1, n_changed
      call schedule_crossing(self, bodies, flight, changed(k), T)
    end do
  contains
    !> Does moving body k reach the sleeping partner of pair q within the step (as the global loop's pass
    !> decides: touching, gap within target + tolerance, or closing on it faster than the
    !> gap allows)? Otherwise the partner stays asleep and supports k like a static body.
    logical function reaches(k, g, nrm)
      integer, intent(in) :: k
      real(dp), intent(in) :: g, nrm(3)
      real(dp) :: closing, toward(3)
      toward = nrm
      if (self%pairs%a(q) /= k) toward = -nrm     ! nrm points from a to b: towards j from k
      closing = max(0.0_dp, dot_product(toward, bodies%v(:, k)))*h + &
                max(0.0_dp, dot_product(toward, flight%acceleration(k, self%gravity)))*h*h + &
                turning_reach(shapes, bodies, k)*h
      reaches = g <= stage%target + stage%tolerance .or. g - (stage%target + stage%tolerance) <= closing
    end function reaches
    recursive subroutine add_member(body)
      integer, intent(in) :: body
      integer :: old
      if (bodies%fixed(body)) return
      if (self%mark(body) == stamp) return
      self%mark(body) = stamp
      call sync(self, bodies, flight, body, T)
      old = self%island_of(body)
      if (old > 0) then
        if (self%islands%islands(old)%t_start + self%islands%islands(old)%step <= T) then
          ! its step ends now too: finished as planned, it joins
          call finish_island(self, stage, bodies, shapes, flight, old, T, members, n_members, err)
          call mark_all()
          return
        end if
      end if
      if (old > 0 .and. can_wait) then
        ! free bodies reaching an island may wait for its next step and join it there: an
        ! island that bodies land on one by one is not cut by each of them
        if (wait_for == 0) wait_for = old
        if (old /= wait_for) several = .true.
        self%mark(body) = 0     ! (not a member: may be reached again)
        return
      end if
      if (old > 0) then
        ! a body of another island: that island's step ends here, all of it joins
        call cut_island(self, stage, bodies, flight, old, T, members, n_members)
        ! (cut_island appended its members; mark them)
        call mark_all()
        return
      end if
      call push(members, n_members, body)
    end subroutine add_member
    subroutine mark_all()
      integer :: kk
      do kk = 1, n_members
        self%mark(members(kk)) = stamp
      end do
    end subroutine mark_all
  end subroutine island_step

  !> After an island step's pass: the impacts at T of the pairs `hold` (those of them in the
  !> step's table) solved again on the pass's velocities, exactly as an impact is (the band
  !> contacts connected to them, inelastic, collision_stage%resolve), so that none of them
  !> approaches when the step's pairs are certified. Without it, a pair between the settling
  !> floor and the floor plus the tolerance that an unconverged pass leaves approaching is in
  !> contact again at once, for ever: its impulse stops the approach, the island steps again,
  !> its pass gives the approach back (docs/contact.md, "Known limits").
  !> Loads stay as the pass left them (zero: a pass gives its members straight flight).
  subroutine hold_pairs(self, stage, bodies, shapes, flight, hold, table, T, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: hold(:), table(:)
    real(dp), intent(in) :: T
    type(error_t), intent(inout) :: err
    integer :: k, n_held
    integer, allocatable :: held(:, :)
    allocate (held(2, size(hold)))
    n_held = 0
    do k = 1, size(hold)
      if (.not. any(table == hold(k))) cycle
      n_held = n_held + 1
      held(:, n_held) = [self%pairs%a(hold(k)), self%pairs%b(hold(k))]
    end do
    if (n_held == 0) return
    stage%n_events = n_held
    if (allocated(stage%event_pairs)) deallocate (stage%event_pairs)
    allocate (stage%event_pairs(2, n_held))
    stage%event_pairs = held(:, 1:n_held)
    call stage%resolve(bodies, shapes, flight, 1.0_dp, 1.0_dp, err, time=T)
    stage%n_events = 0
  end subroutine hold_pairs

  !> Free bodies join island slot (mid-step) as members that fly free until its step ends,
  !> when its next step takes them in; their pairs certified up to there.
  subroutine join_island(self, stage, bodies, shapes, flight, island, joiners, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: island, joiners(:)
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer :: k
    self%stats%joins = self%stats%joins + size(joiners)
    associate (isl => self%islands%islands(island))
      do k = 1, size(joiners)
        call touch_row(self, joiners(k))
        self%island_of(joiners(k)) = island
        self%expiry(joiners(k)) = isl%t_start + isl%step
      end do
    end associate
    call self%islands%append(island, joiners)
    call certify_pairs_of(self, stage, bodies, shapes, flight, joiners, t, err)
  end subroutine join_island

  !> After an impact without contact passes: the bodies that changed get their pairs
  !> certified again and their crossings rescheduled.
  subroutine settle_changed(self, stage, bodies, shapes, flight, changed, t, err)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: changed(:)
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer :: k
    do k = 1, size(changed)
      if (norm2(bodies%x(:, changed(k)) - self%region_x(:, changed(k))) > 0.5_dp*self%margin) then
        call replace(self, stage, bodies, shapes, flight, changed(k), t, err)
        if (err%failed()) return
      end if
    end do
    call certify_pairs_of(self, stage, bodies, shapes, flight, changed, t, err)
    if (err%failed()) return
    do k = 1, size(changed)
      call schedule_crossing(self, bodies, flight, changed(k), t)
    end do
  end subroutine settle_changed

  !> The pass's band pairs, each kept with the island of its moving body (islands(:): the
  !> slots just made), for the island's sleeping at the end of its step.
  subroutine keep_band_pairs(self, stage, bodies, islands)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(in) :: stage
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: islands(:)
    integer :: k, c, island, body
    do c = 1, size(islands)
      associate (isl => self%islands%islands(islands(c)))
        if (.not. allocated(isl%band_pairs)) allocate (isl%band_pairs(2, 4))
        isl%n_band_pairs = 0
      end associate
    end do
    do k = 1, stage%n_band_pairs
      body = stage%band_pairs(1, k)
      if (bodies%fixed(body)) body = stage%band_pairs(2, k)
      if (bodies%fixed(body)) cycle
      island = self%island_of(body)
      if (island == 0) cycle
      associate (isl => self%islands%islands(island))
        if (isl%n_band_pairs == size(isl%band_pairs, 2)) call grow_pairs(isl%band_pairs)
        isl%n_band_pairs = isl%n_band_pairs + 1
        isl%band_pairs(:, isl%n_band_pairs) = stage%band_pairs(:, k)
      end associate
    end do
  end subroutine keep_band_pairs

  subroutine grow_pairs(x)
    integer, allocatable, intent(inout) :: x(:, :)
    integer, allocatable :: y(:, :)
    allocate (y(2, 2*size(x, 2)))
    y(:, 1:size(x, 2)) = x
    call move_alloc(y, x)
  end subroutine grow_pairs

  !> Pair slots into the stage's table (their stored gaps and normals, not in a pass).
  subroutine load_table(self, stage, bodies, slots)
    type(event_loop_t), intent(in) :: self
    type(collision_stage_t), intent(inout) :: stage
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: slots(:)
    integer :: k
    call stage%reserve_table(size(slots), bodies%n_owned + bodies%n_ghost)
    do k = 1, size(slots)
      stage%pairs(:, k) = [self%pairs%a(slots(k)), self%pairs%b(slots(k))]
      stage%pair_gap0(k) = self%pairs%gap(slots(k))
      stage%pair_normal(:, k) = self%pairs%normal(:, slots(k))
      stage%pair_far(k) = self%pairs%far(slots(k))
      stage%pair_in_pass(k) = .false.
    end do
    stage%n_pairs = size(slots)
  end subroutine load_table

  subroutine push(list, n, value)
    integer, allocatable, intent(inout) :: list(:)
    integer, intent(inout) :: n
    integer, intent(in) :: value
    integer, allocatable :: grown(:)
    if (.not. allocated(list)) allocate (list(16))
    if (n == size(list)) then
      allocate (grown(2*size(list)))
      grown(1:n) = list(1:n)
      call move_alloc(grown, list)
    end if
    n = n + 1
    list(n) = value
  end subroutine push

  subroutine grow_logical(x)
    logical, allocatable, intent(inout) :: x(:)
    logical, allocatable :: y(:)
    allocate (y(2*size(x)))
    y(1:size(x)) = x
    call move_alloc(y, x)
  end subroutine grow_logical

  !> Does body i (at t) have a pair within reach of a contact pass over dt_max?
  logical function has_pass_pair(self, stage, bodies, shapes, flight, i, t) result(has)
    type(event_loop_t), intent(inout) :: self
    type(collision_stage_t), intent(in) :: stage
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    real(dp), intent(in) :: t
    integer :: q, m
    real(dp) :: closing
    has = .false.
    q = self%pairs%head(i)
    do while (q > 0)
      m = self%pairs%partner(q, i)
      call sync(self, bodies, flight, m, t)
      ! (certify measured every pair near enough: far ones are not within reach)
      if (.not. self%pairs%far(q)) then
        closing = pass_closing(self, shapes, bodies, i, m, self%dt_max)
        if (self%pairs%gap(q) <= self%band) has = .true.
        if (stage%materials%pair_restitution(bodies%group_id(i), bodies%group_id(m)) <= 0.0_dp .and. &
            self%pairs%gap(q) - (stage%target + stage%tolerance) <= closing) has = .true.
        if (has) return
      end if
      q = self%pairs%next_of(q, i)
    end do
  end function has_pass_pair

end module event_loop
