!> One run: builds shapes and bodies from a deck (or a checkpoint), owns the clock, and
!> drives the loop { choose the step -> advance the bodies -> history, frames, checkpoints }.
!> Each stage reads the state and writes only its own result; only this loop owns time.
module simulation
  use, intrinsic :: iso_fortran_env, only: output_unit
  use kinds, only: dp, i8
  use constants, only: name_length, line_length
  use error_status, only: error_t, ERR_INPUT, ERR_NUMERIC, ERR_CHECKPOINT, ERR_INTERNAL
  use string_utils, only: str, join_path
  use parallel_env, only: parallel_t
  use input_config, only: deck_t, EVENTS_LOCAL, EVENTS_GLOBAL, ROTATION_EXACT
  use shape, only: shape_library_t
  use body_state, only: bodies_t, copy_row
  use body_builder, only: build_shapes, build_bodies, count_bodies
  use ownership, only: contact_possible
  use domain, only: domain_t, box_range_t, suggest_dims
  use migration, only: migrate_bodies, migration_stats_t
  use gid_blocks, only: gather_gid_blocks
  use restart_check, only: check_restored_state, check_same_bodies, compare_decks, deck_change_t
  use deck_reader, only: effective_deck_lines
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
    type(domain_t) :: dom
    real(dp) :: window_end = huge(1.0_dp)     !< the next migration [s]
    real(dp) :: previous_stop = 0.0_dp        !< the last output stop of the local loop [s]
    integer(i8) :: windows = 0                !< windows ended by a migration, this run
    type(migration_stats_t) :: migration
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

contains

  subroutine simulation_init(self, par, deck, output_dir, restart_path, err)
    class(simulation_t), intent(inout) :: self
    type(parallel_t), intent(inout) :: par     !< (a decomposed run makes its Cartesian communicator)
    type(deck_t), intent(in) :: deck
    character(len=*), intent(in) :: output_dir     !< where frames, history, checkpoints go
    character(len=*), intent(in) :: restart_path   !< checkpoint to continue from, or ''
    type(error_t), intent(inout) :: err
    integer, allocatable :: shape_of_group(:)
    type(bodies_t) :: everyone
    type(checkpoint_meta_t) :: meta
    integer(i8) :: first, last, pair(2)
    logical :: contacts
    integer :: k

    self%deck = deck
    self%wall_start = par%wtime()
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
    ! comparison and the choice of owners need them all (O(all bodies) until the domain
    ! decomposition lands).
    call build_bodies(deck, self%shapes, shape_of_group, deck%run%gravity, 1_i8, self%n_total, everyone, err)
    if (err%failed()) return
    if (len_trim(restart_path) > 0) then
      ! Everything about the checkpoint is checked before any output is touched.
      call restore_checkpoint(self, par, restart_path, everyone, meta, err)
      if (err%failed()) return
    else
      call check_initial_overlaps(deck, self%shapes, everyone, err)
      if (err%failed()) return
    end if
    ! (at a restart too: the bodies may have gone far from the origin since the start)
    call check_position_resolution(deck, self%shapes, everyone, &
                                   min_separation_for(deck, smallest_moving_extent(self%shapes, everyone)), &
                                   deck%contact%min_separation <= 0.0_dp, err)
    if (err%failed()) return
    ! One grid box size and one auto minimum separation for every rank: from the smallest
    ! moving body of all (every rank holds every body here); per-body tables are sized
    ! for all of them, so that migration never outgrows them.
    call self%collisions%init(deck, self%shapes, everyone, err)
    if (err%failed()) return
    ! Owners: the bricks of a domain decomposition when no two bodies can interact before
    ! t_end, otherwise every body on rank 0 (contacts across ranks are not built yet).
    contacts = .false.
    if (par%n_ranks > 1) then
      contacts = contact_possible(self%shapes, everyone, deck%run%t_end - self%time, deck%run%gravity, pair, &
                                  2.0_dp*(self%collisions%target + self%collisions%tolerance + &
                                          self%collisions%contact_tolerance))
      if (contacts .and. par%is_root()) then
        write (*, '(a)') 'ricochet: notice: bodies '//str(pair(1))//' and '//str(pair(2))//' may touch before '// &
          't_end, and contacts between bodies of different ranks are not built yet: every body runs on '// &
          'rank 0, the other '//str(par%n_ranks - 1)//' rank(s) wait'
        flush (output_unit)
      end if
      if (.not. contacts) call decompose(self, par, everyone, err)
      if (err%failed()) return
    end if
    if (self%decomposed) then
      call take_brick(everyone, self%dom, self%bodies)
    else
      ! every body on rank 0 (the only rank of a serial run)
      first = 1
      last = merge(self%n_total, 0_i8, par%is_root())
      call take_rows(everyone, first, last, self%bodies)
    end if
    call everyone%free()
    call self%propagator%init(self%bodies%n_owned, deck%integrator)

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

    call self%frames%init(par, self%output_dir, err)
    if (err%failed()) return

    if (len_trim(restart_path) > 0) then
      call self%restart_from(meta)
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
    if (self%local) call self%events%init(self%collisions, self%bodies, self%shapes, self%propagator, &
                                          deck%run%gravity, deck%integrator, self%time, deck%run%dt_max, &
                                          min(deck%run%t_end, self%next_checkpoint), err)
    self%previous_stop = self%time
    if (self%decomposed) self%window_end = self%time + motion_window(self, par)
  end subroutine simulation_init

  !> The bricks of this run on par's ranks (decomposed = .true.), or, when the scene is too
  !> small to give every rank two grid boxes along a split axis, none (a notice; every body
  !> then runs on rank 0). The global box holds every body's bounding sphere at the start.
  subroutine decompose(self, par, everyone, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(inout) :: par
    type(bodies_t), intent(in) :: everyone
    type(error_t), intent(inout) :: err
    real(dp) :: lower(3), upper(3), r
    integer(i8) :: n_boxes(3)
    integer :: dims(3), i
    type(error_t) :: why
    lower = huge(1.0_dp)
    upper = -huge(1.0_dp)
    do i = 1, everyone%n_owned
      r = self%shapes%shapes(everyone%shape_id(i))%bounding_radius
      lower = min(lower, everyone%x(:, i) - r)
      upper = max(upper, everyone%x(:, i) + r)
    end do
    n_boxes = int(floor(upper/self%collisions%box_size) - floor(lower/self%collisions%box_size), i8) + 1
    call suggest_dims(par%n_ranks, self%deck%parallel%dims, dims, why, n_boxes)
    if (why%ok()) call self%dom%init(self%collisions%box_size, lower, upper, dims, par%rank, why)
    if (why%failed() .and. any(self%deck%parallel%dims > 0)) then
      ! dims the deck asked for: an error, not a quiet fallback
      call err%set(ERR_INPUT, self%deck%path//': &parallel: dims = '//str(self%deck%parallel%dims(1))//', '// &
                   str(self%deck%parallel%dims(2))//', '//str(self%deck%parallel%dims(3))//' on '// &
                   str(par%n_ranks)//' ranks: '//trim(why%message))
      return
    end if
    if (why%failed()) then
      if (par%is_root()) then
        write (*, '(a)') 'ricochet: notice: no domain decomposition over '//str(par%n_ranks)//' ranks ('// &
          trim(why%message)//'): every body runs on rank 0'
        flush (output_unit)
      end if
      return
    end if
    call par%cart_create(dims, err)
    if (err%failed()) return
    self%decomposed = .true.
    if (par%is_root()) then
      write (*, '(a)') '  domain decomposition '//str(dims(1))//' x '//str(dims(2))//' x '//str(dims(3))// &
        ' bricks over '//str(self%dom%n_boxes(1))//' x '//str(self%dom%n_boxes(2))//' x '// &
        str(self%dom%n_boxes(3))//' grid boxes of '//str(self%collisions%box_size, '(es10.3)')// &
        ' m (no two bodies can interact before t_end: every rank runs its own)'
      flush (output_unit)
    end if
  end subroutine decompose

  !> The bodies of all whose centre lies in this rank's brick, in global-id order.
  subroutine take_brick(all, dom, owned)
    type(bodies_t), intent(in) :: all
    type(domain_t), intent(in) :: dom
    type(bodies_t), intent(inout) :: owned
    integer :: i, n
    n = 0
    do i = 1, all%n_owned
      if (dom%owner_of(all%x(:, i)) == dom%rank) n = n + 1
    end do
    call owned%allocate(n)
    n = 0
    do i = 1, all%n_owned
      if (dom%owner_of(all%x(:, i)) /= dom%rank) cycle
      n = n + 1
      call copy_row(all, i, owned, n)
    end do
    owned%n_owned = n
    owned%n_ghost = 0
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
  real(dp) function motion_window(self, par) result(window)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    real(dp) :: v(3), a(3), room, below, above, tau, h
    type(box_range_t) :: lower_brick(3), upper_brick(3)
    logical :: has_lower(3), has_upper(3)
    integer :: i, k, c(3)
    h = self%dom%h
    do k = 1, 3
      c = self%dom%coords
      c(k) = c(k) - 1
      has_lower(k) = c(k) >= 0
      if (has_lower(k)) lower_brick(k) = self%dom%brick(self%dom%rank_of(c))
      c = self%dom%coords
      c(k) = c(k) + 1
      has_upper(k) = c(k) < self%dom%dims(k)
      if (has_upper(k)) upper_brick(k) = self%dom%brick(self%dom%rank_of(c))
    end do
    window = huge(1.0_dp)
    do i = 1, self%bodies%n_owned
      if (self%bodies%fixed(i)) cycle
      a = self%propagator%acceleration(i, self%deck%run%gravity)
      if (self%local .and. self%propagator%is_anchored(i)) then
        v = self%propagator%v0(:, i) + (self%time - self%propagator%t0(i))*a
      else
        v = self%bodies%v(:, i)
      end if
      do k = 1, 3
        below = huge(1.0_dp)
        above = huge(1.0_dp)
        if (has_lower(k)) below = self%bodies%x(k, i) - real(lower_brick(k)%lo(k), dp)*h
        if (has_upper(k)) above = real(upper_brick(k)%hi(k) + 1, dp)*h - self%bodies%x(k, i)
        room = 0.9_dp*min(below, above)
        if (room >= huge(1.0_dp)*0.5_dp) cycle
        if (.not. self%local) room = room - h
        room = max(room, 0.0_dp)
        ! the positive root of |v_k| tau + |a_k| tau^2/2 = room, without cancellation
        tau = 2.0_dp*room/max(abs(v(k)) + sqrt(v(k)*v(k) + 2.0_dp*abs(a(k))*room), tiny(1.0_dp))
        window = min(window, tau)
      end do
    end do
    window = par%min(window)
  end function motion_window

  !> A window's end: every body goes to the rank of its brick with its flight record (the
  !> anchor: trajectories go on bit for bit), then the local loop is built again over the
  !> bodies this rank now holds, keeping their anchors.
  subroutine end_window(self, par, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: payload(:, :)
    integer :: i
    ! every body where it is now: it goes to the owner of its position at the window's end
    if (self%local) call self%events%synchronize(self%bodies, self%propagator, self%time)
    call self%propagator%pack_anchors(self%bodies%n_owned, payload)
    call migrate_bodies(par, self%dom, self%bodies, err, stats=self%migration, payload=payload)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'migration failed on another rank')
      return
    end if
    call self%propagator%unpack_anchors(payload, self%deck%integrator)
    self%windows = self%windows + 1
    if (self%local) then
      do i = 1, self%bodies%n_owned
        if (.not. self%bodies%fixed(i) .and. self%propagator%is_anchored(i)) &
          call self%propagator%evaluate(self%bodies, i, self%time, self%deck%run%gravity)
      end do
      call self%events%init(self%collisions, self%bodies, self%shapes, self%propagator, self%deck%run%gravity, &
                            self%deck%integrator, self%time, self%deck%run%dt_max, &
                            min(self%deck%run%t_end, self%next_checkpoint), err, keep_anchors=.true.)
      if (err%failed()) return
    end if
    self%window_end = self%time + motion_window(self, par)
  end subroutine end_window

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
    character(len=line_length), allocatable :: lines(:)
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
    call effective_deck_lines(self%deck, lines)
    call compare_decks(meta%deck_lines, lines, path, changes, err)
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
    call check_initial_overlaps(self%deck, self%shapes, bodies, err)
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
  subroutine restart_from(self, meta)
    class(simulation_t), intent(inout) :: self
    type(checkpoint_meta_t), intent(in) :: meta
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
    self%collisions%stats%events = nint(counter(meta, 'events'), i8)
    self%collisions%stats%contacts = nint(counter(meta, 'contacts'), i8)
    self%collisions%stats%advancement_iterations = nint(counter(meta, 'advancement_iterations'), i8)
    self%collisions%stats%pair_tests = nint(counter(meta, 'pair_tests'), i8)
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

  subroutine simulation_run(self, par, err)
    class(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    real(dp) :: h, t_end, dt_max, target, clock, time_new, h_event, h_planned, h_first
    logical :: checkpointed

    t_end = self%deck%run%t_end
    dt_max = self%deck%run%dt_max
    if (self%local) then
      call run_local(self, par, err)
      return
    end if
    do while (self%time < t_end)
      ! The step: dt_max, shortened to land exactly on the next output, checkpoint or end.
      target = min(t_end, self%next_output, self%next_checkpoint)
      if (target - self%time <= dt_max*(1.0_dp + sliver_fraction)) then
        h = target - self%time
      else
        h = dt_max
      end if
      ! Collisions: no body moves more than one grid box, and the step ends at the earliest
      ! time of contact.
      ! The step is global: the smallest over every rank's bodies (as on one rank), so a run
      ! takes the same steps on any number of ranks.
      h = par%min(self%collisions%limit_step(self%bodies, self%propagator, self%deck%run%gravity, h))
      ! The step's candidate pairs and their gaps, shared by the contact pass and the time
      ! of contact.
      clock = par%wtime()
      call self%collisions%prepare(self%bodies, self%shapes, self%propagator, h, self%deck%run%gravity, err)
      if (err%failed()) return
      call self%collisions%correct_distances(self%bodies, self%shapes, self%propagator)
      self%detection_wall = self%detection_wall + (par%wtime() - clock)
      ! Resting contacts first: their forces over the step become the bodies' loads, so
      ! bodies at rest keep whole steps (docs/contact.md).
      clock = par%wtime()
      call self%collisions%contact_pass(self%bodies, self%shapes, self%propagator, h, self%deck%run%gravity, err)
      if (err%failed()) return
      self%contact_pass_wall = self%contact_pass_wall + (par%wtime() - clock)
      clock = par%wtime()
      h = par%min(self%collisions%limit_step(self%bodies, self%propagator, self%deck%run%gravity, h))
      call self%collisions%earliest_contact(self%bodies, self%shapes, self%propagator, self%time, h, &
                                            self%deck%run%gravity, self%deck%integrator, h_event, err)
      if (err%failed()) return
      ! The earliest contact of any rank ends everybody's step; a rank whose own contacts come
      ! later has no event in it.
      h_first = par%min(h_event)
      if (h_first < h_event) call self%collisions%drop_events()
      h_event = h_first
      self%detection_wall = self%detection_wall + (par%wtime() - clock)
      h_planned = h
      if (h_event < h) then
        h = h_event
        time_new = self%time + h
      else if (h == target - self%time) then
        time_new = target          ! exactly: output times stay k*interval, with no drift
      else
        time_new = self%time + h
      end if
      clock = par%wtime()
      call self%propagator%advance(self%bodies, self%time, time_new, h, self%deck%run%gravity, &
                                   self%deck%integrator, self%flight)
      self%integration_wall = self%integration_wall + (par%wtime() - clock)
      self%step = self%step + 1
      self%last_dt = h
      self%time = time_new
      clock = par%wtime()
      call self%collisions%return_unused_pass(self%bodies, self%propagator, h)
      call self%collisions%resolve(self%bodies, self%shapes, self%propagator, h, h_planned, err, time=self%time)
      if (err%failed()) return
      call self%collisions%settle(self%bodies, self%shapes, self%propagator, h)
      self%resolve_wall = self%resolve_wall + (par%wtime() - clock)
      call write_due_outputs(self, par, t_end, checkpointed, err)
      if (err%failed()) return
      ! (steps move no body more than a grid box, so a window ends at a step's end)
      if (self%decomposed .and. self%time >= self%window_end .and. self%time < t_end) then
        call end_window(self, par, err)
        if (err%failed()) return
      end if
      call progress(self, par)
      ! every step end: every rank is here, all bodies at self%time
      call stop_if_requested(self, par, err)
      if (self%stop_code /= 0 .or. err%failed()) return
    end do
    call self%write_checkpoint_now(par, 'checkpoint_final', err)
    if (err%ok()) call write_events(self, par, err)
  end subroutine simulation_run

  !> The run with the local event loop: events processed up to each output, history,
  !> checkpoint or end time, where every body is evaluated and the outputs written; after a
  !> checkpoint the loop is built again from the state written, as a restart builds it.
  subroutine run_local(self, par, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    real(dp) :: t_end, t_stop, t_hard, clock, t_output
    logical :: checkpointed, window_ends
    integer(i8) :: events_before
    t_end = self%deck%run%t_end
    do while (self%time < t_end)
      t_output = min(t_end, self%next_output, self%next_history, self%next_checkpoint)
      ! (a window that ends before the next output: a migration, nothing written)
      window_ends = self%decomposed .and. self%window_end < t_output
      t_stop = t_output
      if (window_ends) t_stop = self%window_end
      t_hard = min(t_end, self%next_checkpoint)
      clock = par%wtime()
      events_before = self%events%stats%impacts + self%events%stats%island_steps
      call self%events%run_until(self%collisions, self%bodies, self%shapes, self%propagator, t_stop, t_hard, err)
      if (err%failed()) return
      self%detection_wall = self%detection_wall + (par%wtime() - clock)
      ! (events of every rank: the same count on any number of ranks)
      self%step = self%step + par%sum(self%events%stats%impacts + self%events%stats%island_steps - events_before)
      self%time = t_stop
      self%collisions%stats%events = self%events%stats%impacts
      if (window_ends) then
        call end_window(self, par, err)
        if (err%failed()) return
        cycle
      end if
      ! (from the last output stop: the same history on any number of ranks)
      self%last_dt = t_stop - self%previous_stop
      self%previous_stop = t_stop
      clock = par%wtime()
      call self%events%synchronize(self%bodies, self%propagator, self%time)
      self%integration_wall = self%integration_wall + (par%wtime() - clock)
      call write_due_outputs(self, par, t_end, checkpointed, err)
      if (err%failed()) return
      if (checkpointed) then
        ! built again from the state written, exactly as a restart from it builds it
        call self%events%init(self%collisions, self%bodies, self%shapes, self%propagator, self%deck%run%gravity, &
                              self%deck%integrator, self%time, self%deck%run%dt_max, &
                              min(t_end, self%next_checkpoint), err)
        if (err%failed()) return
      end if
      if (self%decomposed .and. self%time >= self%window_end) then
        call end_window(self, par, err)
        if (err%failed()) return
      end if
      call progress(self, par)
      ! Window ends only (not inside run_until): here every rank is, every body is evaluated
      ! at self%time, and a checkpoint is exactly what a scheduled one would be.
      call stop_if_requested(self, par, err)
      if (self%stop_code /= 0 .or. err%failed()) return
    end do
    call self%write_checkpoint_now(par, 'checkpoint_final', err)
    if (err%ok()) call write_events(self, par, err)
  end subroutine run_local

  !> At a point every rank reaches, with every body at self%time: stops the run when some
  !> rank received SIGTERM or SIGINT or this run's wall time reached &run wall_limit (one
  !> collective for both), after writing checkpoint_signal.h5 or checkpoint_wall_limit.h5
  !> and the event log. Sets stop_code, stop_reason, stop_checkpoint; the driver says it.
  subroutine stop_if_requested(self, par, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    integer :: reason
    character(len=:), allocatable :: name
    if (self%time >= self%deck%run%t_end) return    ! done anyway: the normal end follows
    ! Signal numbers (2, 15) outrank the wall limit (1): a signal usually means SIGKILL soon.
    reason = stop_signal_received()
    if (reason == 0 .and. self%deck%run%wall_limit > 0.0_dp) then
      if (par%wtime() - self%wall_start >= self%deck%run%wall_limit) reason = 1
    end if
    reason = par%max(reason)
    if (reason == 0) return
    if (reason == 1) then
      name = 'checkpoint_wall_limit'
      self%stop_code = exit_wall_limit
      self%stop_reason = 'wall_limit = '//str(self%deck%run%wall_limit, '(g0.6)')//' s reached'
    else
      name = 'checkpoint_signal'
      self%stop_code = 128 + reason
      self%stop_reason = 'stopped by '//signal_name(reason)
    end if
    call self%write_checkpoint_now(par, name, err)
    if (err%ok()) call write_events(self, par, err)
    self%stop_checkpoint = join_path(self%output_dir, name//'.h5')
  end subroutine stop_if_requested

  !> What is due at self%time, in both loops: a history row (at each history multiple,
  !> output time and the end), a frame (output times and the end), a checkpoint (its
  !> times before the end; checkpointed says one was written).
  subroutine write_due_outputs(self, par, t_end, checkpointed, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    real(dp), intent(in) :: t_end
    logical, intent(out) :: checkpointed
    type(error_t), intent(inout) :: err
    logical :: hits_output
    hits_output = self%time >= self%next_output
    checkpointed = self%time >= self%next_checkpoint .and. self%time < t_end
    if (hits_output .or. self%time >= t_end .or. self%time >= self%next_history) then
      call self%record_history(par, err)
      if (err%failed()) return
      self%next_history = next_multiple(self%time, self%history_interval)
    end if
    if (hits_output .or. self%time >= t_end) then
      call self%write_frame(par, err)
      if (err%failed()) return
    end if
    if (checkpointed) then
      call self%write_checkpoint_now(par, 'checkpoint_'// &
                                     str6(nint(self%time/self%deck%output%checkpoint_interval)), err)
    end if
  end subroutine write_due_outputs

  !> The event log (&output event_log), one file per rank (events.csv on one rank).
  subroutine write_events(self, par, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: name
    if (.not. self%collisions%log_events) return
    name = 'events.csv'
    if (par%n_ranks > 1) name = 'events_rank'//str(par%rank)//'.csv'
    if (.not. allocated(self%collisions%log_rows)) allocate (self%collisions%log_rows(8, 0))
    call write_event_log(join_path(self%output_dir, name), self%collisions%log_rows, self%collisions%n_log, err)
  end subroutine write_events

  !> The first multiple of interval after time (k interval computed, never accumulated).
  pure real(dp) function next_multiple(time, interval) result(next)
    real(dp), intent(in) :: time, interval
    real(dp) :: k
    k = aint(time/interval) + 1.0_dp
    next = k*interval
    if (next <= time) next = (k + 1.0_dp)*interval
  end function next_multiple

  function str6(i) result(text)
    integer, intent(in) :: i
    character(len=6) :: text
    write (text, '(i6.6)') i
  end function str6

  subroutine record_history(self, par, err)
    class(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    type(system_totals_t) :: now
    type(history_record_t) :: rec
    real(dp) :: scale, expected_p(3)
    call compute_totals(par, self%bodies, self%deck%run%gravity, now)
    rec%time = self%time
    rec%dt = self%last_dt
    rec%steps = self%step
    rec%kinetic_translational = now%kinetic_translational
    rec%kinetic_rotational = now%kinetic_rotational
    rec%potential = now%potential
    rec%momentum = now%momentum
    rec%angular_momentum = now%angular_momentum
    rec%wall_time = self%wall_before + (par%wtime() - self%wall_start)
    ! (over every rank: the same row on any number of ranks)
    rec%events = par%sum(self%collisions%stats%events)
    rec%contacts = par%sum(self%collisions%stats%contacts)
    rec%advancement_iterations = par%sum(self%collisions%stats%advancement_iterations)
    rec%min_separation = par%min(self%collisions%stats%min_separation)
    rec%asleep = self%collisions%sleep%n_asleep
    call self%history%write(par, rec, err)
    ! Conservation errors relative to the initial kinetic plus |potential| energy scale, and
    ! to the momentum scale: meaningful whatever the origin of the potential.
    ! (or, for a system that starts at rest at zero potential, the energy it has released)
    scale = max(self%initial%kinetic_translational + self%initial%kinetic_rotational + &
                abs(self%initial%potential), now%kinetic_translational + now%kinetic_rotational, &
                abs(now%potential - self%initial%potential), tiny(1.0_dp))
    self%max_energy_error = max(self%max_energy_error, abs(now%energy() - self%initial%energy())/scale)
    expected_p = self%initial%momentum + self%initial%mass*self%deck%run%gravity*self%time
    ! Relative to |P0| or |P0 + M g t|, or, when those are small (a gas at rest as a whole:
    ! 1e15 "relative" error from round-off over nothing), to the momentum the kinetic energy
    ! could carry, sqrt(2 T M) (never below |P|, by Cauchy-Schwarz).
    scale = max(norm2(self%initial%momentum), norm2(expected_p), &
                sqrt(2.0_dp*max(self%initial%kinetic_translational, now%kinetic_translational)*now%mass), &
                tiny(1.0_dp))
    self%max_momentum_error = max(self%max_momentum_error, norm2(now%momentum - expected_p)/scale)
    ! Relative to |L0|, or, when the system started with little or none, to the angular
    ! momentum its kinetic energy could carry (sqrt(2 T I)), so spin out of nothing counts.
    scale = max(norm2(self%initial%angular_momentum), now%angular_momentum_scale, tiny(1.0_dp))
    self%max_angular_momentum_error = &
      max(self%max_angular_momentum_error, norm2(now%angular_momentum - self%initial%angular_momentum)/scale)
  end subroutine record_history

  subroutine write_frame(self, par, err)
    class(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    type(bodies_t) :: blocks
    if (self%deck%output%check_overlaps) then
      ! Each rank checks its bodies: all of them on rank 0 when contacts are possible, and
      ! blocks that cannot touch otherwise (ownership): the verdict is agreed by all.
      call check_initial_overlaps(self%deck, self%shapes, self%bodies, err, time=self%time)
      if (par%any(err%failed()) .and. err%ok()) call err%set(ERR_INTERNAL, &
        'another rank found bodies that interpenetrate (&output check_overlaps)')
      if (err%failed()) return
    end if
    if (.not. self%deck%output%write_frames) then
      self%next_output = huge(1.0_dp)     ! no frames: steps need not land on output times
      return
    end if
    if (par%n_ranks > 1) then
      ! in global-id blocks, so that the file is the same whoever owned which body
      call gather_gid_blocks(par, self%bodies, self%n_total, blocks, err)
      if (par%any(err%failed())) then
        if (err%ok()) call err%set(ERR_INTERNAL, 'frame: another rank could not take its bodies')
        return
      end if
      call self%frames%write(par, self%time, blocks, self%shapes, self%group_names, err)
    else
      call self%frames%write(par, self%time, self%bodies, self%shapes, self%group_names, err)
    end if
    ! Output times are multiples of the interval, computed, not accumulated.
    self%next_output = real(self%frames%n_frames, dp)*self%output_interval
  end subroutine write_frame

  subroutine write_checkpoint_now(self, par, name, err)
    class(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: name
    type(error_t), intent(inout) :: err
    type(checkpoint_meta_t) :: meta
    type(bodies_t) :: blocks
    ! Checkpoint k falls at k * interval: the next one follows from the time alone, so a
    ! restarted run numbers and places its checkpoints as the first run did.
    if (self%time >= self%next_checkpoint) then
      self%next_checkpoint = (anint(self%time/self%deck%output%checkpoint_interval) + 1.0_dp)* &
                             self%deck%output%checkpoint_interval
    end if
    ! Sleeping islands wake, as a run restarted from here starts with every body awake.
    call self%collisions%wake_all(self%bodies, self%propagator)
    call self%fill_meta(par, meta)
    if (par%n_ranks > 1) then
      ! in global-id blocks: the same file on any number of ranks, whoever owned which body
      call gather_gid_blocks(par, self%bodies, self%n_total, blocks, err)
      if (par%any(err%failed())) then
        if (err%ok()) call err%set(ERR_INTERNAL, "checkpoint '"//name//"': another rank could not take its bodies")
        return
      end if
      call write_checkpoint(par, join_path(self%output_dir, name//'.h5'), meta, blocks, err)
    else
      call write_checkpoint(par, join_path(self%output_dir, name//'.h5'), meta, self%bodies, err)
    end if
    ! Exact flight re-anchors at the checkpoint's state, as a run restarted from it will, and
    ! no body carries the contact pass's load into the next step (the candidate pairs of a
    ! step's start depend on it: a restart has none).
    call self%propagator%clear_all_loads()
    call self%propagator%release_all()
    call self%collisions%resting%forget()
  end subroutine write_checkpoint_now

  !> What a checkpoint needs besides the bodies, and the deck fingerprint it is checked with.
  subroutine fill_meta(self, par, meta)
    class(simulation_t), intent(in) :: self
    type(parallel_t), intent(in) :: par
    type(checkpoint_meta_t), intent(out) :: meta
    integer :: k
    meta%time = self%time
    meta%step = self%step
    meta%n_frames = self%frames%n_frames
    meta%frame_times = self%frames%frame_times(1:self%frames%n_frames)
    meta%next_output_time = self%next_output
    meta%next_checkpoint_time = self%next_checkpoint
    meta%wall_time_before = self%wall_before + (par%wtime() - self%wall_start)
    meta%e0 = self%initial%energy()
    meta%p0 = self%initial%momentum
    meta%l0 = self%initial%angular_momentum
    meta%mass0 = self%initial%mass
    meta%n_bodies_total = self%n_total
    meta%title = self%deck%run%title
    meta%checksum = bodies_checksum(par, self%bodies)
    allocate (meta%shape_digests(self%shapes%n_shapes), meta%shape_labels(self%shapes%n_shapes))
    do k = 1, self%shapes%n_shapes
      meta%shape_digests(k) = self%shapes%shapes(k)%digest
      meta%shape_labels(k) = self%shapes%shapes(k)%label
    end do
    call effective_deck_lines(self%deck, meta%deck_lines)
    meta%counter_names = [character(len=name_length) :: 'initial_kinetic_translational', &
                          'initial_kinetic_rotational', 'initial_potential', 'max_energy_error', &
                          'max_momentum_error', 'max_angular_momentum_error', 'events', 'contacts', &
                          'advancement_iterations', 'pair_tests', 'min_separation']
    meta%counters = [self%initial%kinetic_translational, self%initial%kinetic_rotational, self%initial%potential, &
                     self%max_energy_error, self%max_momentum_error, self%max_angular_momentum_error, &
                     real(self%collisions%stats%events, dp), real(self%collisions%stats%contacts, dp), &
                     real(self%collisions%stats%advancement_iterations, dp), &
                     real(self%collisions%stats%pair_tests, dp), self%collisions%stats%min_separation]
  end subroutine fill_meta

  subroutine progress(self, par)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    real(dp) :: now, rate, left
    now = par%wtime()
    if (now - self%last_progress < self%deck%output%progress_interval) return
    self%last_progress = now
    if (.not. par%is_root()) return
    rate = self%time/max(now - self%wall_start + self%wall_before, tiny(1.0_dp))
    left = (self%deck%run%t_end - self%time)/max(rate, tiny(1.0_dp))
    write (*, '(a,es11.4,a,es11.4,a,i0,a,es10.3,a,f0.1,a)') '  t = ', self%time, ' / ', self%deck%run%t_end, &
      ' s   steps ', self%step, '   ', rate, ' sim s per wall s   about ', left, ' s left'
    flush (output_unit)   ! a job killed later keeps its log up to here
  end subroutine progress

  subroutine simulation_summary(self, par)
    class(simulation_t), intent(in) :: self
    type(parallel_t), intent(in) :: par
    real(dp) :: wall, per_step, min_sep, load(3, 3)
    integer(i8) :: events, contacts, pair_tests, migrated, bytes, messages
    wall = par%wtime() - self%wall_start
    ! The load of each rank (min, mean, max over ranks): bodies owned at the end, events, busy
    ! time (everything but waiting in collectives is not split out yet: the run's wall time).
    load(:, 1) = real(self%bodies%n_owned, dp)
    load(:, 2) = real(self%collisions%stats%events + self%events%stats%island_steps, dp)
    load(:, 3) = self%detection_wall + self%integration_wall + self%contact_pass_wall + self%resolve_wall
    load(1, :) = [par%min(load(1, 1)), par%min(load(1, 2)), par%min(load(1, 3))]
    load(2, :) = [par%sum(load(2, 1)), par%sum(load(2, 2)), par%sum(load(2, 3))]/real(par%n_ranks, dp)
    load(3, :) = [par%max(load(3, 1)), par%max(load(3, 2)), par%max(load(3, 3))]
    migrated = par%sum(self%migration%bodies_left)
    bytes = par%sum(self%migration%bytes_sent)
    messages = par%sum(self%migration%messages_sent)
    ! Over every rank (collective, before rank 0 alone goes on to print).
    events = par%sum(self%collisions%stats%events)
    contacts = par%sum(self%collisions%stats%contacts)
    pair_tests = par%sum(self%collisions%stats%pair_tests)
    min_sep = par%min(self%collisions%stats%min_separation)
    if (.not. par%is_root()) return
    per_step = wall/max(real(self%step - self%first_step, dp), 1.0_dp)
    write (*, '(a)') 'ricochet: run finished at t = '//str(self%time, '(g0.6)')//' s'
    write (*, '(a,es10.3,a,i0,a,i0,a)') '  wall time            ', wall, ' s on ', par%n_ranks, ' rank(s), ', &
      self%step - self%first_step, ' steps in this run'
    write (*, '(a,es10.3,a,es10.3,a)') '  time per step        ', per_step, ' s (', &
      per_step/max(real(self%n_total, dp), 1.0_dp), ' s per body)'
    write (*, '(a,es10.3,a,es10.3,a)') '  integration time     ', self%integration_wall, ' s (', &
      real(self%n_total, dp)*real(self%step - self%first_step, dp)/max(self%integration_wall, tiny(1.0_dp)), &
      ' body updates per s)'
    if (self%local) then
      associate (ev => self%events%stats)
        write (*, '(a)') '  time by phase        island steps (contact passes) '//str(ev%wall_islands, '(es9.3)')// &
          ' s, impacts '//str(ev%wall_impacts, '(es9.3)')//' s, certificates and box crossings '// &
          str(ev%wall_detection, '(es9.3)')//' s, evaluating bodies for outputs '// &
          str(self%integration_wall, '(es9.3)')//' s'
      end associate
    else
      write (*, '(a)') '  time by phase        contact pass '//str(self%contact_pass_wall, '(es9.3)')// &
        ' s, detection '//str(self%detection_wall, '(es9.3)')//' s, impacts and sleeping '// &
        str(self%resolve_wall, '(es9.3)')//' s'
    end if
    write (*, '(a,i0,a,i0,a)') '  bodies               ', self%n_total, ' in ', self%shapes%n_shapes, ' distinct shapes'
    if (par%n_ranks > 1) then
      write (*, '(a)') '  ranks (min/mean/max) bodies '//str(load(1, 1), '(g0.4)')//' / '//str(load(2, 1), '(g0.4)')// &
        ' / '//str(load(3, 1), '(g0.4)')//', events '//str(load(1, 2), '(g0.4)')//' / '//str(load(2, 2), '(g0.4)')// &
        ' / '//str(load(3, 2), '(g0.4)')//', busy '//str(load(1, 3), '(es9.3)')//' / '//str(load(2, 3), '(es9.3)')// &
        ' / '//str(load(3, 3), '(es9.3)')//' s'
      if (self%decomposed) then
        write (*, '(a)') '  windows              '//str(self%windows)//' ended by a migration: '//str(migrated)// &
          ' bodies changed rank, '//str(messages)//' messages, '//str(bytes)//' bytes'
      else
        write (*, '(a)') '  windows              none: every body on rank 0 (bodies may interact)'
      end if
    end if
    if (events > 0) write (*, '(a)') &
      '  (with contacts, energy is an invariant only for e = 1, momentum and angular momentum only '// &
      'without fixed bodies)'
    write (*, '(a,es10.3,a)') '  energy error (max)   ', self%max_energy_error, '  (relative to kinetic + |potential|)'
    write (*, '(a,es10.3,a)') '  momentum error (max) ', self%max_momentum_error, &
      '  (P - P0 - M g t, relative to max(|P0 + M g t|, sqrt(2 T M)))'
    write (*, '(a,es10.3,a)') '  ang. momentum error  ', self%max_angular_momentum_error, &
      '  (about the centre of mass, relative to max(|L0|, sqrt(2 T I)))'
    write (*, '(a,i0,a,i0,a,i0)') '  rotation iterations  ', self%flight%iterations_total, ' (max per update ', &
      self%flight%iterations_max, '), not converged: ', self%flight%not_converged
    write (*, '(a,i0,a,i0,a,i0,a,i0,a)') '  contact events       ', events, ' (', &
      contacts, ' contact points, ', self%collisions%impulses%groups, ' impulse groups, ', &
      self%collisions%stats%corrections, ' distance corrections, '// &
      str(self%collisions%stats%corrections_capped)//' of them cut to half the band)'
    if (self%local) then
      associate (ev => self%events%stats)
        write (*, '(a)') '  local events         '//str(ev%impacts)//' impacts, '//str(ev%island_steps)//' island steps ('// &
          str(ev%body_steps)//' body-steps, '//str(ev%island_cuts)//' cut by impacts, '//str(ev%joins)// &
          ' bodies waited to join), '//str(ev%enters)//' pairs came within reach of a pass'
        write (*, '(a)') '  pair certificates    '//str(ev%certificates)//' ('//str(ev%far_certificates)// &
          ' from bounding volumes), '//str(ev%crossings)//' box crossings'
        write (*, '(a)') '  body updates         '//str(ev%evaluations)//' for events, '//str(ev%output_evaluations)// &
          ' for outputs, '//str(ev%trajectory_changes)//' trajectory changes; '// &
          str(self%events%bodies_unchanged(self%bodies))//' bodies never changed trajectory'
      end associate
    end if
    write (*, '(a,i0,a,i0,a,i0,a)') '  time of contact      ', pair_tests, ' pair queries, ', &
      self%collisions%stats%advancement_iterations, ' advancement iterations (', self%collisions%stats%capped, &
      ' capped, '//str(self%collisions%stats%plane_skips)//' started from a second-order safe time)'
    associate (rest => self%collisions%resting)
      if (rest%stats%passes > 0) then
        write (*, '(a,i0,a,i0,a,i0,a,i0,a)') '  resting contact      ', rest%stats%passes, ' steps, ', &
          rest%stats%contacts, ' contact points (', rest%stats%warm_starts, ' warm-started), ', &
          rest%stats%loaded, ' body-steps under load'
        write (*, '(a,i0,a,i0,a,i0,a,i0,a)') '  contact solver       ', rest%pgs%solves, ' PGS solves, ', &
          rest%pgs%sweeps, ' sweeps (max ', rest%pgs%max_sweeps_seen, ', capped ', rest%pgs%cap_hits, &
          '), '//str(rest%exact%groups)//' exact groups'
        if (rest%stats%stuck > 0) write (*, '(a)') '  static friction      '//str(rest%stats%stuck)// &
          ' group-steps held still exactly (sticking solve)'
        if (rest%stats%staggered_solves > 0) write (*, '(a)') '  friction groups      '// &
          str(rest%stats%staggered_solves)//' staggered solves, '//str(rest%stats%staggered_rounds)//' rounds ('// &
          str(rest%stats%staggered_capped)//' capped), '//str(rest%stats%projections)//' finished by the projection'
      end if
    end associate
    associate (sleep => self%collisions%sleep)
      if (sleep%enabled()) write (*, '(a,i0,a,i0,a,i0,a)') '  sleeping             ', sleep%sleeps, &
        ' bodies put to sleep, ', sleep%wakes, ' woken, ', sleep%n_asleep_at_wake_all, ' asleep at the end'
    end associate
    if (min_sep < huge(1.0_dp)) then
      write (*, '(a,es10.3,a,es10.3,a)') '  smallest separation  ', min_sep, &
        ' m (minimum separation ', self%collisions%target, ' m)'
    else
      write (*, '(a)') '  smallest separation  no two bodies ever came near'
    end if
    write (*, '(a,i0,a)') '  frames written       ', self%frames%n_frames, ' in '//self%output_dir
    flush (output_unit)
  end subroutine simulation_summary

  subroutine simulation_free(self)
    class(simulation_t), intent(inout) :: self
    call self%bodies%free()
    call self%shapes%free()
  end subroutine simulation_free

end module simulation
