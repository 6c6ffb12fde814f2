!> Cross-rank windows (docs/architecture.md, "Cross-rank contacts: windows with ghosts"): a
!> decomposed run whose bodies may meet across bricks, for scenes without contact passes
!> (elastic pairs, no gravity). Every window, from a time every rank has reached with every
!> event before it processed:
!>  1. start: every body to the rank of its brick (migration with its anchor and version),
!>     the halo of two rings received as ghosts with their anchors and owners, the fixed
!>     bodies of the scene added as ghosts where not held; the loop follows (remap_bodies:
!>     owned pairs keep their certificates, the ghosts' pairs are made and certified; pairs
!>     of two ghosts are their owners');
!>  2. a speculative run to the next output time, in which an impact with a moving ghost
!>     (its pair, or its impulse group) is taken as any other, the ghosts' copies given new
!>     trajectories too: the other rank takes the same impact from the same trajectories
!>     (docs/architecture.md, "Cross-rank impacts computed twice"). It stops only at an
!>     impact whose group reaches a ghost not all of whose neighbourhood is held here
!>     (t_cross) or at a box crossing that leaves what the halo covers (t_halo: a body held
!>     as a ghost elsewhere leaving its brick, or another body coming within two boxes of a
!>     neighbouring brick). Every new trajectory of a row another rank holds goes to the
!>     loop's change log (time, flight record);
!>  3. the change logs go to the neighbours (exchange_changes): two logs of one body agree
!>     on a prefix of shared changes; after it the owner's next change is where the other
!>     copy went stale (changed_at), the other rank's next change an impact the owner did
!>     not take alike (a mismatch, t_mismatch, which joins t_cross); t_both, the first time
!>     two bodies of two ranks, each stale on the other's rank, may meet; a t_cross whose
!>     ghost was stale by then is void (the time it went stale counts instead);
!>  4. one allreduce of t_cross and min(t_halo, t_both): if both are at or after the output
!>     time the window stands. Otherwise every rank restores the window's start (bodies,
!>     flight records, the loop, the stage's counters) and runs again, to t_cross without
!>     the events there (if it comes first) or to the other time with them; at t_cross the
!>     impacts needing ghosts are taken by the owner of the pair's lower global id with the
!>     ghosts (the cross phase), and the ghosts it changed go to their owners, who take
!>     their new rows and anchors bit for bit.
!> Why it is exact: within a window a pair with a ghost is certified by the rank whose copy
!> of the other body is right, right until both copies went stale (t_both); no rank's event
!> depends on a body it does not hold (t_halo, with the brick size of cross_box_size) or on
!> an impact another rank takes (t_cross); an impact both ranks took used only copies that
!> were right (an input that was not shows as a mismatch at its time, before which every
!> change of every shared body agrees bit for bit); the run repeated from the start is the
!> same deterministic run, cut earlier. Events are the one-rank run's, at the same times
!> with the same bits: times of contact are functions of the two trajectories
!> (time_of_contact's canonical crossing, taken as an absolute time), whatever certificate
!> found them.
submodule (simulation) simulation_cross_windows
  use event_loop, only: CROSS_OFF, CROSS_SPECULATE, CROSS_RERUN, CROSS_PHASE, STOP_CROSS, STOP_HALO
  use event_loop, only: event_stats_t, copy_loop
  use halo_exchange, only: exchange_halo
  use body_packing, only: pack_bodies, unpack_blocks
  use sorting, only: sort_index_keys, find_key
  use deck_reader, only: DECK_AUTO
  implicit none

  integer, parameter :: halo_rings = 2
  real(dp), parameter :: never = 1.0e30_dp
  !> windows in a row that end at the time they started before the run stops with an error
  integer, parameter :: max_stuck_windows = 1000
  !> &parallel window_events auto: the fastest of 66, 133 and 330 events per rank on the
  !> 100,000-sphere gas over 0.25 s on two ranks (docs/benchmarks.md)
  real(dp), parameter :: auto_window_events = 150.0_dp

contains

  module procedure cross_box_size
    real(dp) :: r_max, band, h
    integer :: i
    r_max = 0.0_dp
    do i = 1, everyone%n_owned
      if (everyone%fixed(i)) cycle
      r_max = max(r_max, self%shapes%shapes(everyone%shape_id(i))%bounding_radius)
    end do
    band = self%collisions%target + self%collisions%tolerance + self%collisions%contact_tolerance
    h = self%collisions%box_size
    self%cross_r_max = r_max
    ! (auto: one collision grid box, the fastest of 0, h/2, h, 2h on gases of 27,000 and
    ! 100,000 spheres: fewer migrations against more ghosts, docs/benchmarks.md)
    self%cross_skin = self%deck%parallel%skin
    if (self%cross_skin < 0.0_dp) self%cross_skin = h
    ! (a relative 1e-6 for the round-off of box edges)
    box = max(h, (2.0_dp*r_max + band + h + self%cross_skin)*(1.0_dp + 1.0e-6_dp))
  end procedure cross_box_size

  module procedure run_cross_windows
    real(dp) :: t_end, t_output, t_hard, t_cross, t_late, t_v, clock, t_window
    real(dp) :: window_length, window_events, run_start_time
    integer(i8) :: run_start_step
    type(collision_stage_t) :: saved_stage   ! (its counters and sleeping state only)
    type(event_loop_t) :: saved_loop
    integer, allocatable :: owner(:)
    logical, allocatable :: frontier(:)
    real(dp), allocatable :: changed_at(:)
    integer(i8), allocatable :: versions(:), start_versions(:)
    integer, allocatable :: dropped(:)
    logical :: need_full
    real(dp) :: t_stale, t_both, t_known, t_mismatch
    integer :: n_log, stuck, i, k
    integer(i8) :: events_before
    logical :: checkpointed, exclusive, to_known
    t_end = self%deck%run%t_end
    ! Window length (docs/architecture.md, "Window length"): a window repeated to an earlier
    ! time costs its whole speculative run and the repetition, so long windows lose when
    ! cross-rank events come often, and every window costs a start and a save. Windows aim
    ! at window_events events per rank, from the run's event rate so far (global counts
    ! and simulated times: the same on every rank, and the same windows in every run);
    ! the first is a hundredth of what is left, and one at most twice the one before.
    window_events = self%deck%parallel%window_events
    if (window_events == DECK_AUTO) window_events = auto_window_events
    run_start_time = self%time
    run_start_step = self%step
    window_length = (t_end - self%time)/100.0_dp
    stuck = 0
    need_full = .true.
    allocate (dropped(0))
    ! (the impacts so far: a restart's count on rank 0, as the other counters)
    self%events%stats%impacts = self%collisions%stats%events
    do while (self%time < t_end)
      t_output = min(t_end, self%next_output, self%next_history, self%next_checkpoint)
      t_window = min(t_output, self%time + window_length)
      if (t_window <= self%time) t_window = t_output
      t_hard = min(t_end, self%next_checkpoint)
      clock = par%wtime()
      if (need_full) then
        ! (the ghosts whose pair a cross phase dropped come again afresh, with all their pairs)
        do i = 1, size(dropped)
          k = dropped(i) - self%bodies%n_owned
          if (k >= 1 .and. k <= size(self%ghost_versions)) self%ghost_versions(k) = -2_i8
        end do
        call start_window(self, par, t_hard, owner, frontier, err)
        if (err%failed()) return
      else
        call light_start(self, par, owner, frontier, start_versions, dropped, t_hard, err)
        if (err%failed()) return
        self%cross_count(5) = self%cross_count(5) + 1
      end if
      dropped = [integer ::]
      start_versions = self%events%version(1:self%bodies%n_owned)
      self%cross_wall(1) = self%cross_wall(1) + (par%wtime() - clock)
      self%cross_count(1) = self%cross_count(1) + 1
      ! the window's start, to come back to (the event log's rows are only appended: their count)
      call save_state()
      events_before = self%events%stats%impacts
      ! the earliest halo stop known now (queued box crossings that will leave the halo's
      ! coverage): every rank's run ends just before it, and if none meets anything earlier
      ! the cross phase follows (the events at that time, the crossing's halo stop making
      ! the next start a full one) with no repetition
      t_known = par%min(self%events%queued_halo_time(self%bodies, self%propagator))
      to_known = t_known <= t_window
      self%events%cross_mode = CROSS_SPECULATE
      call self%events%run_until(self%collisions, self%bodies, self%shapes, self%propagator, min(t_known, t_window), &
                                 t_hard, err, exclusive=to_known)
      if (par%any(err%failed())) then
        if (err%ok()) call err%set(ERR_INTERNAL, 'a cross-rank window failed on another rank')
        return
      end if
      t_cross = never
      t_late = never
      if (self%events%stop_kind == STOP_CROSS) t_cross = self%events%stop_time
      if (self%events%stop_kind == STOP_HALO) t_late = self%events%stop_time
      call self%events%close_paths(self%bodies, self%propagator, min(t_window, self%events%stop_time))
      call exchange_changes(self, par, owner, changed_at, t_both, t_mismatch, err)
      if (err%failed()) return
      t_late = min(t_late, t_both)
      if (t_cross < never .and. self%events%n_stop_rows > 0) then
        ! a cross-rank impact with a ghost whose copy here was stale by then is none: this
        ! rank's copy is stale from that change on (the next window's ghosts are fresh)
        t_stale = minval(changed_at(self%events%stop_rows(1:self%events%n_stop_rows)))
        if (t_stale <= t_cross) then
          t_late = min(t_late, t_stale)
          t_cross = never
        end if
      end if
      ! (an impact taken here that its bodies' owners did not take the same: events up to
      ! it stand, those at it go to the cross phase)
      t_cross = min(t_cross, t_mismatch)
      t_cross = par%min(t_cross)
      t_late = par%min(t_late)
      ! (every rank's run reached t_known with nothing before it: the known impact's time is
      ! a cross time, and nobody's run went past it)
      if (to_known) t_cross = min(t_cross, t_known)
      if (t_cross > t_window .and. t_late >= t_window) then
        ! the window stands: every event up to its end (the output time, or the window
        ! length's end before it) is the one-rank run's
        self%time = t_window
      else
        clock = par%wtime()
        exclusive = t_cross <= t_late
        t_v = min(t_cross, t_late)
        if (.not. (to_known .and. exclusive .and. t_v == t_known)) then
          self%cross_count(2) = self%cross_count(2) + 1
          call restore_state()
          self%events%cross_mode = CROSS_RERUN
          self%events%rerun_to = t_v
          if (err%ok()) call self%events%run_until(self%collisions, self%bodies, self%shapes, self%propagator, t_v, &
                                                   t_hard, err, exclusive=exclusive)
          if (par%any(err%failed())) then
            if (err%ok()) call err%set(ERR_INTERNAL, 'a repeated cross-rank window failed on another rank')
            return
          end if
        end if
        ! (a run repeated to t_v with the events there that stopped at a cross-rank impact
        ! at t_v, which every rank's speculative run may have taken and a halo stop or
        ! t_both cut short: the cross phase takes the rest at t_v)
        if (.not. exclusive) exclusive = par%any(self%events%stop_kind == STOP_CROSS)
        if (exclusive) then
          ! the cross phase: every event at t_v, those needing ghosts by the lower id's owner
          self%cross_count(3) = self%cross_count(3) + 1
          ! (the ghosts their owners changed: a group with one is left to the next window)
          self%events%ghost_changed_at = changed_at
          self%events%cross_mode = CROSS_PHASE
          versions = self%events%version(1:self%bodies%n_total())
          call self%events%run_until(self%collisions, self%bodies, self%shapes, self%propagator, t_v, t_hard, err)
          if (par%any(err%failed())) then
            if (err%ok()) call err%set(ERR_INTERNAL, 'a cross-rank impact failed on another rank')
            return
          end if
          dropped = [dropped, self%events%dropped_rows(1:self%events%n_dropped_rows)]
          call send_ghost_updates(self, par, owner, versions, t_v, err)
          if (err%failed()) return
        end if
        if (t_v <= self%time) then
          stuck = stuck + 1
          if (stuck > max_stuck_windows) then
            call err%set(ERR_INTERNAL, 'cross-rank windows: '//str(max_stuck_windows)//' windows in a row ended '// &
                         'at t = '//str(self%time)//' s where they started (last pair '// &
                         str(self%events%stop_pair(1))//', '//str(self%events%stop_pair(2))//')')
            return
          end if
        else
          stuck = 0
        end if
        self%time = t_v
        self%cross_wall(2) = self%cross_wall(2) + (par%wtime() - clock)
      end if
      self%events%cross_mode = CROSS_OFF
      call self%propagator%stop_journal()
      call self%bodies%stop_journal()
      call self%events%stop_journal()
      ! the next window starts light (only the ghosts that changed come again, and the bodies
      ! that came near a neighbouring brick) unless a body left its brick somewhere
      need_full = par%any(self%events%halo_exit_seen)
      ! (events of every rank: the same count on any number of ranks)
      self%step = self%step + par%sum(self%events%stats%impacts - events_before)
      self%collisions%stats%events = self%events%stats%impacts
      if (self%step > run_start_step .and. self%time > run_start_time) then
        window_length = min(2.0_dp*window_length, window_events*real(par%n_ranks, dp)* &
                            (self%time - run_start_time)/real(self%step - run_start_step, dp))
      else
        window_length = 2.0_dp*window_length
      end if
      if (self%time < t_output) cycle
      ! the outputs at t_output (of owned bodies: the writers and sums skip the ghosts)
      self%last_dt = self%time - self%previous_stop
      self%previous_stop = self%time
      clock = par%wtime()
      call evaluate_owned(self)
      self%integration_wall = self%integration_wall + (par%wtime() - clock)
      call write_due_outputs(self, par, t_end, checkpointed, err)
      if (err%failed()) return
      if (checkpointed) then
        ! built again from the state written, exactly as a restart from it builds it (and as
        ! the one-rank loop is): every owned body anchored there, no ghosts until the next window
        self%bodies%n_ghost = 0
        if (allocated(self%ghost_versions)) deallocate (self%ghost_versions)
        need_full = .true.
        dropped = [integer ::]
        call self%events%init(self%collisions, self%bodies, self%shapes, self%propagator, self%deck%run%gravity, &
                              self%deck%integrator, self%time, self%deck%run%dt_max, min(t_end, self%next_checkpoint), err)
        if (par%any(err%failed())) then
          if (err%ok()) call err%set(ERR_INTERNAL, 'building the loop after a checkpoint failed on another rank')
          return
        end if
      end if
      call progress(self, par)
      call stop_if_requested(self, par, err)
      if (self%stop_code /= 0 .or. err%failed()) return
    end do
    self%bodies%n_ghost = 0
    call self%write_checkpoint_now(par, 'checkpoint_final', err)
    if (err%ok()) call write_events(self, par, err)
  contains
    subroutine save_state()
      call self%bodies%start_journal()
      call self%propagator%start_journal()
      n_log = self%collisions%n_log
      ! Of the collision stage, what an elastic event changes and later events or the
      ! summary read: counters and the sleeping state. Its gap memo is a cache (an entry
      ! answers only the same poses, bit for bit), the rest scratch of each event, and the
      ! event log's rows are only appended (a repeated run overwrites those past n_log).
      saved_stage%stats = self%collisions%stats
      saved_stage%impulses = self%collisions%impulses
      saved_stage%impact_friction = self%collisions%impact_friction
      saved_stage%residual_pgs = self%collisions%residual_pgs
      saved_stage%sleep = self%collisions%sleep
      call copy_loop(saved_loop, self%events, restoring=.false.)
    end subroutine save_state
    subroutine restore_state()
      call self%bodies%roll_back(err)
      call self%propagator%roll_back()
      self%collisions%stats = saved_stage%stats
      self%collisions%impulses = saved_stage%impulses
      self%collisions%impact_friction = saved_stage%impact_friction
      self%collisions%residual_pgs = saved_stage%residual_pgs
      self%collisions%sleep = saved_stage%sleep
      self%collisions%n_log = n_log
      call copy_loop(self%events, saved_loop, restoring=.true.)
    end subroutine restore_state
  end procedure run_cross_windows

  !> Every owned moving body evaluated at self%time from its anchor.
  subroutine evaluate_owned(self)
    type(simulation_t), intent(inout) :: self
    integer :: i
    do i = 1, self%bodies%n_owned
      if (self%bodies%fixed(i) .or. .not. self%propagator%is_anchored(i)) cycle
      call self%propagator%evaluate(self%bodies, i, self%time, self%deck%run%gravity)
    end do
  end subroutine evaluate_owned


  !> A window's start at self%time: migration, ghosts (halo and fixed bodies), the loop.
  !> owner(row): the rank owning each row (ghosts: the rank that sent it; -1: a fixed body
  !> every rank holds). frontier(row): an owned body that other ranks hold as a ghost.
  subroutine start_window(self, par, t_hard, owner, frontier, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    real(dp), intent(in) :: t_hard
    integer, allocatable, intent(out) :: owner(:)
    logical, allocatable, intent(out) :: frontier(:)
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: sent(:, :), received(:, :), words(:, :), held(:, :), versions(:)
    integer(i8), allocatable :: old_sorted(:, :), old_local(:), old_owner(:), ghost_versions(:)
    integer(i8), allocatable :: zeros(:)
    integer, allocatable :: rows(:), order(:), new_index(:), old_order(:), halo_rows(:)
    integer :: n_words, i, k, n_owned, n_halo, mid, n_old_owned, n_old_ghosts, r
    logical :: rebuilt, in_place
    ! the last window's ghosts: a ghost that comes again with its owner's same version (the
    ! same trajectory) keeps its row's pairs and certificates, as does a fixed body; the
    ! others go with their pairs
    n_old_owned = self%bodies%n_owned
    n_old_ghosts = self%bodies%n_ghost
    if (.not. allocated(self%ghost_versions)) allocate (self%ghost_versions(0))
    if (size(self%ghost_versions) /= n_old_ghosts) n_old_ghosts = 0
    allocate (old_local(n_old_ghosts), old_owner(n_old_ghosts))
    if (n_old_ghosts > 0) then
      old_local = self%events%version(n_old_owned + 1:n_old_owned + n_old_ghosts)
      old_owner = self%ghost_versions
    end if
    call gid_index(self%bodies%gid(n_old_owned + 1:n_old_owned + n_old_ghosts), old_sorted, old_order)
    ! every owned body at self%time
    call evaluate_owned(self)
    versions = self%events%version(1:self%bodies%n_owned)
    in_place = self%in_own_bricks .and. self%bodies%n_ghost == 0
    if (in_place) then
      ! (the first window after simulation_init's take_brick, at the time it took the
      ! bodies: every body is where migration would leave it, in gid order, and its flight
      ! record where it is; 0.1 s of copying and sorting for 50,000 bodies a rank, and the
      ! records of every owned body packed, 36 MB of fresh pages)
      allocate (new_index(self%bodies%n_owned))
      new_index = [(i, i=1, self%bodies%n_owned)]
    else
      call migrate_owned(self, par, new_index, err, versions)
    end if
    self%in_own_bricks = .false.
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'migration failed on another rank')
      return
    end if
    n_owned = self%bodies%n_owned
    n_words = self%propagator%anchor_words()
    ! owned bodies a neighbour holds as ghosts: within halo_rings boxes of a side with one
    ! (the rows the halo exchange sends: only theirs need a record to travel with them)
    allocate (frontier(n_owned))
    if (allocated(self%zone)) deallocate (self%zone)
    allocate (self%zone(n_owned))
    do i = 1, n_owned
      self%zone(i) = near_sides(self%dom, self%bodies%x(:, i), halo_rings)
      frontier(i) = self%zone(i) /= 0
    end do
    halo_rows = pack([(i, i=1, n_owned)], frontier)
    allocate (sent(1 + n_words, size(halo_rows)))
    sent(1, :) = par%rank
    call self%propagator%pack_anchors(0, words, halo_rows)
    sent(2:, :) = words
    call exchange_halo(par, self%dom, self%bodies, halo_rings, err, versions=versions, ghost_versions=ghost_versions, &
                       payload=sent, ghost_payload=received, payload_rows=halo_rows)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'halo exchange failed on another rank')
      return
    end if
    n_halo = self%bodies%n_ghost
    ! the fixed bodies no row holds yet (a search of each static's gid among the rows held)
    call gid_index(self%bodies%gid(1:n_owned + n_halo), held, order)
    allocate (rows(0))
    do k = 1, self%statics%n_owned
      if (find_key(held, size(order), [self%statics%gid(k)]) == 0) rows = [rows, k]
    end do
    if (size(rows) > 0) call self%bodies%append_rows(self%statics, rows, .true.)
    ! every row's flight record (a fixed body has none: zeros); the owned rows' are in place
    call self%propagator%grow(self%bodies%n_total())
    allocate (zeros(n_words))
    zeros = 0
    do r = n_owned + 1, self%bodies%n_total()
      if (r <= n_owned + n_halo) then
        call self%propagator%set_record(r, received(2:, r - n_owned))
      else
        call self%propagator%set_record(r, zeros)
      end if
    end do
    allocate (owner(self%bodies%n_total()))
    owner = -1
    owner(1:n_owned) = par%rank
    if (n_halo > 0) owner(n_owned + 1:n_owned + n_halo) = int(received(1, 1:n_halo))
    ! the loop follows: owned bodies keep their pairs and certificates, the ghosts (rows past
    ! n_owned) arrive and only their pairs are made and certified (event_loop%remap_bodies)
    versions = [versions(1:n_owned), [(0_i8, i=n_owned + 1, self%bodies%n_total())]]
    ghost_versions = [ghost_versions(1:n_halo), [(-1_i8, i=n_halo + 1, self%bodies%n_ghost)]]
    do r = n_owned + 1, self%bodies%n_total()
      mid = find_key(old_sorted, n_old_ghosts, [self%bodies%gid(r)])
      if (mid == 0) cycle
      k = old_order(mid)
      if (old_owner(k) == ghost_versions(r - n_owned)) then
        new_index(n_old_owned + k) = r
        versions(r) = old_local(k)
      end if
    end do
    call move_alloc(ghost_versions, self%ghost_versions)
    call self%events%remap_bodies(self%collisions, self%bodies, self%shapes, self%propagator, new_index, versions, &
                                  self%time, t_hard, err, rebuilt)
    if (err%ok() .and. rebuilt) call err%set(ERR_INTERNAL, 'cross-rank window: the loop was built again at t = '// &
                                             str(self%time)//' s')
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'a cross-rank window''s start failed on another rank')
      return
    end if
    call self%events%start_cross_window(self%bodies)
    call watch_halo(self)
  end subroutine start_window

  !> A light window start (docs/architecture.md, "Light window starts"), allowed while no
  !> owned body has left its brick since the last full start (no halo_exit_seen): every
  !> rank's rows stay as they are, nothing migrates, and only two kinds of owned bodies go
  !> to the neighbours, evaluated at self%time, with their flight records and versions (one
  !> alltoallv): the frontier bodies (held as ghosts elsewhere) whose trajectory changed
  !> since the last start, and, where this rank's run saw a body come within two boxes of a
  !> side it was not sent to (halo_seen), every body now so (re-zoned: its zone grows and
  !> it joins the frontier). A rank holding one as a ghost takes row, record and version bit
  !> for bit and the loop takes it as a new trajectory (take_ghost_trajectories; unless the
  !> record is the one it holds, a trajectory both ranks took in the window: only the
  !> version then), as it
  !> takes the ghosts whose pair a cross phase dropped (dropped: rows), whose pairs it makes
  !> again; a rank whose halo holds one it does not hold yet appends it as a ghost row (in
  !> global-id order), which the loop takes as a full start takes an arrival (remap_bodies:
  !> placed, its pairs made and certified). Every ghost then follows its owner's trajectory
  !> and every body within the halo of a rank is held there, as after a full start, so the
  !> window that follows is the same; a full start's migration and two-ring exchange were
  !> O(bodies per rank), this is O(changed frontier bodies) (O(owned bodies) for the scan
  !> of a re-zoning start). Collective.
  subroutine light_start(self, par, owner, frontier, start_versions, dropped, t_hard, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    integer, allocatable, intent(inout) :: owner(:)
    logical, allocatable, intent(inout) :: frontier(:)
    integer(i8), intent(in) :: start_versions(:)
    integer, intent(in) :: dropped(:)
    real(dp), intent(in) :: t_hard
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: words(:, :), extra(:, :), got(:, :), keys(:, :), new_keys(:, :), versions(:), record(:)
    real(dp), allocatable :: part(:), send(:), recv(:)
    integer, allocatable :: rows(:), counts(:), neighbours(:), order(:), taken(:), new_rows(:), new_order(:), &
                            new_index(:)
    logical, allocatable :: take(:)
    type(bodies_t) :: arrived
    integer :: n0, ng, n_before, n_rows, n_scan, i, k, r, mid, w, sides
    real(dp) :: slack
    logical :: rezone, send_it, rebuilt
    n0 = self%bodies%n_owned
    ng = self%bodies%n_ghost
    rezone = self%events%halo_seen
    ! the changed frontier bodies and the re-zoned ones, at the window's start
    allocate (rows(16))
    n_rows = 0
    n_scan = min(n0, size(frontier), size(start_versions))
    do i = 1, n_scan
      if (self%bodies%fixed(i)) cycle
      if (.not. (frontier(i) .and. self%events%version(i) /= start_versions(i))) cycle
      call self%propagator%evaluate(self%bodies, i, self%time, self%deck%run%gravity)
      call push_row(i)
    end do
    if (rezone) then
      ! every owned body now within two boxes of a side it was not sent to, so that it joins
      ! the halo before it stops a window of its own; one is at most the loop's margin (half
      ! a collision box) from where it was last placed (region_x), so only those whose
      ! placement lies within a box of such a side are evaluated (evaluating every owned
      ! body was most of a light start: 11 ms for 50,000 spheres). A body the filter passed
      ! over wrongly would only stop a later window (the loop checks every placement).
      slack = self%collisions%box_size
      do i = 1, n_scan
        if (self%bodies%fixed(i)) cycle
        if (iand(possible_sides(self%events%region_x(:, i)), not(self%zone(i))) == 0) cycle
        call self%propagator%evaluate(self%bodies, i, self%time, self%deck%run%gravity)
        sides = near_sides(self%dom, self%bodies%x(:, i), halo_rings)
        if (iand(sides, not(self%zone(i))) == 0) cycle
        ! (sent already as a changed frontier body, or not)
        send_it = .not. (frontier(i) .and. self%events%version(i) /= start_versions(i))
        self%zone(i) = ior(self%zone(i), sides)
        frontier(i) = .true.
        self%cross_count(6) = self%cross_count(6) + 1
        if (send_it) call push_row(i)
      end do
    end if
    rows = rows(1:n_rows)
    call self%propagator%pack_anchors(n0, words, rows)
    w = size(words, 1)
    ! (record, version, sending rank)
    allocate (extra(w + 2, n_rows))
    extra(1:w, :) = words
    extra(w + 1, :) = self%events%version(rows)
    extra(w + 2, :) = int(par%rank, i8)
    call pack_bodies(self%bodies, rows, part, extra_of_rows=extra)
    allocate (record(w))
    neighbours = self%dom%neighbours()
    allocate (counts(0:par%n_ranks - 1), send(0))
    counts = 0
    do r = 0, par%n_ranks - 1
      if (.not. any(neighbours == r) .or. r == par%rank) cycle
      counts(r) = size(part)
      send = [send, part]
    end do
    call par%alltoallv(send, counts, recv, err)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'a light window start failed on another rank')
      return
    end if
    ! the ghost rows by gid
    allocate (take(ng), new_rows(0))
    take = .false.
    call gid_index(self%bodies%gid(n0 + 1:n0 + ng), keys, order)
    call unpack_blocks(recv, arrived, err, got)
    do k = 1, merge(arrived%n_owned, 0, err%ok())
      mid = find_key(keys, ng, [arrived%gid(k)])
      if (mid == 0) then
        ! (a neighbour's body this rank does not hold: a ghost from now on if its halo has it)
        if (self%dom%in_halo(arrived%x(:, k), halo_rings)) new_rows = [new_rows, k]
        cycle
      end if
      i = order(mid)
      self%ghost_versions(i) = got(w + 1, k)
      ! (a trajectory this rank took with its owner in the last window, bit for bit: its
      ! pairs' certificates stand)
      call self%propagator%record_of(n0 + i, record)
      if (all(record == got(1:w, k))) cycle
      call copy_row(arrived, k, self%bodies, n0 + i)
      call self%propagator%set_record(n0 + i, got(1:w, k))
      take(i) = .true.
    end do
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'a light window start failed on another rank')
      return
    end if
    if (size(new_rows) > 0) then
      ! the new ghosts appended in global-id order, with their records, versions and owners;
      ! the loop takes them as arrivals (every other row keeps its number)
      call gid_index(arrived%gid(new_rows), new_keys, new_order)
      new_rows = new_rows(new_order)
      n_before = self%bodies%n_total()
      call self%bodies%append_rows(arrived, new_rows, .true.)
      call self%propagator%grow(self%bodies%n_total())
      do k = 1, size(new_rows)
        call self%propagator%set_record(n_before + k, got(1:w, new_rows(k)))
      end do
      owner = [owner(1:n_before), int(got(w + 2, new_rows))]
      self%ghost_versions = [self%ghost_versions, got(w + 1, new_rows)]
      versions = [self%events%version(1:n_before), [(0_i8, k=1, size(new_rows))]]
      new_index = [(i, i=1, n_before)]
      call self%events%remap_bodies(self%collisions, self%bodies, self%shapes, self%propagator, new_index, versions, &
                                    self%time, t_hard, err, rebuilt)
      if (err%ok() .and. rebuilt) call err%set(ERR_INTERNAL, 'light window start: the loop was built again at t = '// &
                                               str(self%time)//' s')
    end if
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'a light window start failed on another rank')
      return
    end if
    do k = 1, size(dropped)
      i = dropped(k) - n0
      if (i < 1 .or. i > ng) cycle
      ! (a dropped ghost its owner did not send, as it did not change it: its row evaluated
      ! here at the window's start, from the record it has, as a received row would be)
      if (.not. take(i)) call self%propagator%evaluate(self%bodies, n0 + i, self%time, self%deck%run%gravity)
      take(i) = .true.
    end do
    taken = pack([(n0 + i, i=1, ng)], take)
    call self%events%take_ghost_trajectories(self%collisions, self%bodies, self%shapes, self%propagator, taken, &
                                             self%time, err)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'a light window start failed on another rank')
      return
    end if
    call self%events%start_cross_window(self%bodies)
    call watch_halo(self)
  contains
    !> The sides (as near_sides) a body placed at x may be near, at most slack from x.
    pure integer function possible_sides(x) result(sides)
      real(dp), intent(in) :: x(3)
      integer :: k
      sides = 0
      do k = 1, 3
        if (x(k) - slack < self%events%watch_lo(k)) sides = ibset(sides, 2*k - 2)
        if (x(k) + slack >= self%events%watch_hi(k)) sides = ibset(sides, 2*k - 1)
      end do
    end function possible_sides
    subroutine push_row(row)
      integer, intent(in) :: row
      if (n_rows == size(rows)) rows = [rows, rows]
      n_rows = n_rows + 1
      rows(n_rows) = row
    end subroutine push_row
  end subroutine light_start

  !> The loop's regions of halo stops and of complete impulse groups for this window (see
  !> event_loop's in_zone and complete_lo; the bounds: cross_box_size).
  subroutine watch_halo(self)
    type(simulation_t), intent(inout) :: self
    type(box_range_t) :: mine
    real(dp) :: h, reach
    integer :: k
    mine = self%dom%brick(self%dom%rank)
    h = self%dom%h
    reach = halo_rings*h - 0.5_dp*self%collisions%box_size - self%cross_skin - 2.0_dp*self%cross_r_max - &
            (self%collisions%target + self%collisions%tolerance + self%collisions%contact_tolerance)
    do k = 1, 3
      self%events%watch_lo(k) = -never
      self%events%watch_hi(k) = never
      self%events%complete_lo(k) = -never
      self%events%complete_hi(k) = never
      self%events%brick_lo(k) = -never
      self%events%brick_hi(k) = never
      if (self%dom%face_neighbour(2*k - 1) >= 0) then
        self%events%watch_lo(k) = real(mine%lo(k) + halo_rings, dp)*h
        self%events%brick_lo(k) = real(mine%lo(k), dp)*h - self%cross_skin
        self%events%complete_lo(k) = real(mine%lo(k), dp)*h - reach
      end if
      if (self%dom%face_neighbour(2*k) >= 0) then
        self%events%watch_hi(k) = real(mine%hi(k) + 1 - halo_rings, dp)*h
        self%events%brick_hi(k) = real(mine%hi(k) + 1, dp)*h + self%cross_skin
        self%events%complete_hi(k) = real(mine%hi(k) + 1, dp)*h + reach
      end if
    end do
    if (allocated(self%events%zone_sides)) deallocate (self%events%zone_sides)
    allocate (self%events%zone_sides(self%bodies%n_total()))
    self%events%zone_sides = 0
    if (allocated(self%zone)) self%events%zone_sides(1:min(size(self%zone), self%bodies%n_owned)) = &
      self%zone(1:min(size(self%zone), self%bodies%n_owned))
  end subroutine watch_halo


  !> The sides of this rank's brick with a neighbouring brick within rings boxes of which
  !> point lies (what the halo exchange sends it to): bit 2k-2 the lower side of axis k,
  !> 2k-1 the upper.
  integer function near_sides(dom, point, rings) result(sides)
    type(domain_t), intent(in) :: dom
    real(dp), intent(in) :: point(3)
    integer, intent(in) :: rings
    type(box_range_t) :: mine
    integer(i8) :: box(3)
    integer :: k
    mine = dom%brick(dom%rank)
    box = dom%box_of(point)
    sides = 0
    do k = 1, 3
      if (dom%face_neighbour(2*k - 1) >= 0 .and. box(k) - mine%lo(k) < rings) sides = ibset(sides, 2*k - 2)
      if (dom%face_neighbour(2*k) >= 0 .and. mine%hi(k) - box(k) < rings) sides = ibset(sides, 2*k - 1)
    end do
  end function near_sides

  !> The window's change logs compared with the neighbours' (docs/architecture.md,
  !> "Cross-rank impacts computed twice"). Every rank sends each neighbour, for every row
  !> another rank holds that changed in its run (its owned frontier bodies: the owner's log;
  !> its ghosts: a holder's log), the global id, the sending rank, whose log it is, the box
  !> the centre swept from its first change (owned rows), the radius, and the changes in
  !> the order taken (time, flight record; one alltoallv). Two logs of one body agree on a
  !> prefix of shared changes (the same time and record, bit for bit: both ranks took the
  !> same impact from the same trajectories); after it, the owner's next change is where
  !> the holder's copy went stale, and the holder's next change is one the owner did not
  !> make (a mismatch: an impact taken from a stale copy, or with a group not all known).
  !> changed_at(row): for a ghost row, when its copy here went stale (never if not).
  !> t_mismatch: the earliest mismatch this rank sees [s] (every event before it is the
  !> one-rank run's; events at it are not).
  !> t_both: the first time from which two bodies of two ranks, each stale on the other
  !> rank, may meet [s]: each rank certifies its pairs with ghosts against its copy of the
  !> ghost's trajectory, which is right until that copy goes stale (a contact is then found
  !> by the rank whose copy is right); two that both went stale (at t_a there, t_b here)
  !> are seen by nobody from max(t_a, t_b) on, so any such two whose swept boxes come
  !> within their radii and the band give max(t_a, t_b), whether or not a pair of them was
  !> ever made (their copies may have been far apart). Collective.
  subroutine exchange_changes(self, par, owner, changed_at, t_both, t_mismatch, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    integer, intent(in) :: owner(:)     !< the rank owning each row (see start_window)
    real(dp), allocatable, intent(out) :: changed_at(:)
    real(dp), intent(out) :: t_both, t_mismatch
    type(error_t), intent(inout) :: err
    !> gid, sending rank, owning rank (the sender's: the owner's log; another: a holder's),
    !> changes, box lower (3) and upper (3), radius; then per change its time and record
    integer, parameter :: head = 11
    real(dp), allocatable :: mine(:), send(:), recv(:), stale_there(:, :), first_time(:)
    integer(i8), allocatable :: log_keys(:, :), ghost_keys(:, :), owned_keys(:, :), run_keys(:, :)
    integer, allocatable :: counts(:), neighbours(:), by_row(:), run_start(:), run_rows(:), ghost_order(:), &
                            owned_runs(:), owned_order(:)
    integer :: w, n_log, n_runs, i, k, j, m, p, n0, ng, n_total, nc, at, mid, o, source, n_owned_runs
    real(dp) :: band, reach, glo(3), ghi(3), stale, mismatch
    real(dp), allocatable :: other_lo(:, :), other_hi(:, :), other_radius(:), other_stale(:)
    integer :: n_other
    logical :: owners
    t_both = never
    t_mismatch = never
    n0 = self%bodies%n_owned
    ng = self%bodies%n_ghost
    n_total = n0 + ng
    allocate (changed_at(n_total))
    changed_at = never
    w = self%propagator%anchor_words()
    ! the log's entries by row, each row's in the order taken (a stable sort)
    n_log = self%events%n_change_log
    allocate (log_keys(1, n_log))
    if (n_log > 0) log_keys(1, :) = int(self%events%change_log_row(1:n_log), i8)
    call sort_index_keys(log_keys, by_row)
    allocate (run_start(n_log + 1), run_rows(n_log))
    n_runs = 0
    do k = 1, n_log
      if (k == 1) then
        n_runs = 1
      else if (log_keys(1, by_row(k)) /= log_keys(1, by_row(k - 1))) then
        n_runs = n_runs + 1
      else
        cycle
      end if
      run_start(n_runs) = k
      run_rows(n_runs) = int(log_keys(1, by_row(k)))
    end do
    run_start(n_runs + 1) = n_log + 1
    ! (rows ascending: searched by find_key)
    allocate (run_keys(1, n_runs))
    run_keys(1, :) = int(run_rows(1:n_runs), i8)
    ! this rank's logs, for every neighbour
    allocate (mine(n_runs*head + n_log*(1 + w)))
    at = 0
    do k = 1, n_runs
      i = run_rows(k)
      nc = run_start(k + 1) - run_start(k)
      mine(at + 1) = transfer(self%bodies%gid(i), 1.0_dp)
      mine(at + 2) = real(par%rank, dp)
      mine(at + 3) = real(merge(par%rank, owner(i), i <= n0), dp)
      mine(at + 4) = real(nc, dp)
      mine(at + 5:at + 10) = 0.0_dp
      if (i <= n0) then
        mine(at + 5:at + 7) = self%events%path_lo(:, i)
        mine(at + 8:at + 10) = self%events%path_hi(:, i)
      end if
      mine(at + 11) = self%shapes%shapes(self%bodies%shape_id(i))%bounding_radius
      at = at + head
      do j = run_start(k), run_start(k + 1) - 1
        m = by_row(j)
        mine(at + 1) = self%events%change_log_time(m)
        mine(at + 2:at + 1 + w) = transfer(self%events%change_log_words(:, m), 1.0_dp, w)
        at = at + 1 + w
      end do
    end do
    neighbours = self%dom%neighbours()
    allocate (counts(0:par%n_ranks - 1), send(0))
    counts = 0
    do k = 0, par%n_ranks - 1
      if (k == par%rank .or. .not. any(neighbours == k)) cycle
      counts(k) = at
      send = [send, mine(1:at)]
    end do
    call par%alltoallv(send, counts, recv, err)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'exchanging the change logs failed on another rank')
      return
    end if
    ! the runs of owned rows by gid, and the ghost rows by gid
    owned_runs = pack([(k, k=1, n_runs)], run_rows(1:n_runs) <= n0)
    n_owned_runs = size(owned_runs)
    call gid_index(self%bodies%gid(run_rows(owned_runs)), owned_keys, owned_order)
    call gid_index(self%bodies%gid(n0 + 1:n_total), ghost_keys, ghost_order)
    ! stale_there(k, p): from when neighbour p's copy of owned run k is stale; by default
    ! from its first change (p holds it and took none of its changes, or does not hold it)
    allocate (stale_there(n_owned_runs, size(neighbours)), first_time(n_owned_runs))
    do k = 1, n_owned_runs
      first_time(k) = self%events%change_log_time(by_row(run_start(owned_runs(k))))
      stale_there(k, :) = first_time(k)
    end do
    ! (at most one entry per head received)
    m = size(recv)/head
    allocate (other_lo(3, m), other_hi(3, m), other_radius(m), other_stale(m))
    n_other = 0
    at = 0
    do while (at + head <= size(recv))
      source = nint(recv(at + 2))
      owners = nint(recv(at + 3)) == source
      nc = nint(recv(at + 4))
      glo = recv(at + 5:at + 7)
      ghi = recv(at + 8:at + 10)
      p = findloc(neighbours, source, 1)
      if (owners) then
        ! another rank's body: compared with this rank's copy, if it holds one
        stale = recv(at + head + 1)
        mid = find_key(ghost_keys, ng, [transfer(recv(at + 1), 1_i8)])
        if (mid > 0) then
          i = n0 + ghost_order(mid)
          call compare(recv(at + head + 1:at + head + nc*(1 + w)), nc, row_log(i), stale, mismatch)
          changed_at(i) = stale
          t_mismatch = min(t_mismatch, mismatch)
        end if
        if (stale < never) then
          n_other = n_other + 1
          other_lo(:, n_other) = glo
          other_hi(:, n_other) = ghi
          other_radius(n_other) = recv(at + 11)
          other_stale(n_other) = stale
        end if
      else if (nint(recv(at + 3)) == par%rank) then
        ! another rank's copy of a body of this one: the owner's log (empty if it made no change)
        mid = 0
        if (n_owned_runs > 0) mid = find_key(owned_keys, n_owned_runs, [transfer(recv(at + 1), 1_i8)])
        if (mid == 0) then
          t_mismatch = min(t_mismatch, recv(at + head + 1))
        else
          o = owned_order(mid)
          call compare_owned(owned_runs(o), stale, mismatch)
          if (p > 0) stale_there(o, p) = stale
          t_mismatch = min(t_mismatch, mismatch)
        end if
      end if
      at = at + head + nc*(1 + w)
    end do
    ! two bodies stale on each other's ranks whose swept boxes come within reach
    band = self%collisions%target + self%collisions%tolerance + self%collisions%contact_tolerance
    do k = 1, n_other
      do j = 1, n_owned_runs
        o = run_rows(owned_runs(j))
        reach = self%shapes%shapes(self%bodies%shape_id(o))%bounding_radius + other_radius(k) + band
        if (any(self%events%path_lo(:, o) - reach > other_hi(:, k)) .or. &
            any(self%events%path_hi(:, o) + reach < other_lo(:, k))) cycle
        t_both = min(t_both, max(minval(stale_there(j, :)), other_stale(k)))
      end do
    end do
  contains
    !> The log entries of row i (positions in the change log, in the order taken).
    function row_log(i) result(entries)
      integer, intent(in) :: i
      integer, allocatable :: entries(:)
      integer :: r
      allocate (entries(0))
      r = find_key(run_keys, n_runs, [int(i, i8)])
      if (r > 0) entries = by_row(run_start(r):run_start(r + 1) - 1)
    end function row_log
    !> An owner's log (received: nc changes) against this rank's entries of the body.
    subroutine compare(owner_log, nc, entries, stale, mismatch)
      real(dp), intent(in) :: owner_log(:)
      integer, intent(in) :: nc
      integer, intent(in) :: entries(:)
      real(dp), intent(out) :: stale, mismatch
      integer :: c, q
      c = 1
      do while (c <= nc .and. c <= size(entries))
        q = (c - 1)*(1 + w)
        if (owner_log(q + 1) /= self%events%change_log_time(entries(c))) exit
        if (any(transfer(owner_log(q + 2:q + 1 + w), 1_i8, w) /= self%events%change_log_words(:, entries(c)))) exit
        c = c + 1
      end do
      stale = never
      if (c <= nc) stale = owner_log((c - 1)*(1 + w) + 1)
      mismatch = never
      if (c <= size(entries)) mismatch = self%events%change_log_time(entries(c))
    end subroutine compare
    !> This rank's log of its owned run r against a holder's log received at recv(at+1:).
    subroutine compare_owned(r, stale, mismatch)
      integer, intent(in) :: r
      real(dp), intent(out) :: stale, mismatch
      integer :: c, q, n_mine, e
      n_mine = run_start(r + 1) - run_start(r)
      c = 1
      do while (c <= nc .and. c <= n_mine)
        q = at + head + (c - 1)*(1 + w)
        e = by_row(run_start(r) + c - 1)
        if (recv(q + 1) /= self%events%change_log_time(e)) exit
        if (any(transfer(recv(q + 2:q + 1 + w), 1_i8, w) /= self%events%change_log_words(:, e))) exit
        c = c + 1
      end do
      stale = never
      if (c <= n_mine) stale = self%events%change_log_time(by_row(run_start(r) + c - 1))
      mismatch = never
      if (c <= nc) mismatch = recv(at + head + (c - 1)*(1 + w) + 1)
    end subroutine compare_owned
  end subroutine exchange_changes

  !> After a cross phase at t: every ghost whose trajectory this rank changed in it goes to its
  !> owner (row and flight record, one alltoallv), who takes both bit for bit. A body
  !> changed at t by two ranks (its owner, or two others) would need their groups solved
  !> together: an error naming it (not built yet; no validation scene has one).
  subroutine send_ghost_updates(self, par, owner, versions, t, err)
    type(simulation_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    integer, intent(in) :: owner(:)
    integer(i8), intent(in) :: versions(:)     !< every row's version before the phase
    real(dp), intent(in) :: t
    type(error_t), intent(inout) :: err
    integer(i8), allocatable :: words(:, :), got(:, :), keys(:, :)
    real(dp), allocatable :: send(:), part(:), recv(:)
    integer, allocatable :: counts(:), rows(:), changed(:), order(:)
    logical, allocatable :: updated(:)
    type(bodies_t) :: arrived
    integer :: n0, r, i, k, row, mid
    n0 = self%bodies%n_owned
    ! the ghosts this rank changed in the phase (those its run changed before, its owner did
    ! too: the window's change logs agreed up to the phase) (O(ghosts), not O(rows held))
    changed = pack([(i, i=n0 + 1, self%bodies%n_total())], &
                   [(self%events%version(i) /= versions(i), i=n0 + 1, self%bodies%n_total())])
    allocate (counts(0:par%n_ranks - 1), send(0))
    do r = 0, par%n_ranks - 1
      counts(r) = 0
      if (size(changed) == 0) cycle
      rows = pack(changed, owner(changed) == r)
      if (size(rows) == 0) cycle
      call self%propagator%pack_anchors(0, words, rows)
      call pack_bodies(self%bodies, rows, part, extra_of_rows=words)
      counts(r) = size(part)
      send = [send, part]
      self%cross_count(4) = self%cross_count(4) + size(rows)
    end do
    call par%alltoallv(send, counts, recv, err)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'sending cross-rank impacts failed on another rank')
      return
    end if
    allocate (updated(n0))
    updated = .false.
    call unpack_blocks(recv, arrived, err, got)
    if (err%ok() .and. arrived%n_owned > 0) then
      ! the owned rows by gid (a search per arrival, not a scan of every owned row)
      call gid_index(self%bodies%gid(1:n0), keys, order)
    end if
    do k = 1, merge(arrived%n_owned, 0, err%ok())
      row = 0
      mid = find_key(keys, n0, [arrived%gid(k)])
      if (mid > 0) row = order(mid)
      if (row == 0) then
        call err%set(ERR_INTERNAL, 'cross-rank impact at t = '//str(t)//' s: body '//str(arrived%gid(k))// &
                     ' is not owned by the rank its new trajectory was sent to')
        exit
      end if
      if (updated(row) .or. self%events%version(row) /= versions(row)) then
        call err%set(ERR_INTERNAL, 'cross-rank impacts at t = '//str(t)//' s: body '//str(arrived%gid(k))// &
                     ' was changed by two ranks at once (impulse groups spanning ranks at one time are '// &
                     'not built yet)')
        exit
      end if
      updated(row) = .true.
      call copy_row(arrived, k, self%bodies, row)
      call self%propagator%set_record(row, got(:, k))
    end do
    if (err%ok()) call self%events%take_trajectories(self%collisions, self%bodies, self%shapes, self%propagator, &
                                                     pack([(i, i=1, self%bodies%n_owned)], updated), t, err)
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'a cross-rank impact failed on another rank')
    end if
  end subroutine send_ghost_updates

  !> Global ids sorted for find_key (keys(1, m)), order(m) the position in gids of keys(1, m).
  subroutine gid_index(gids, keys, order)
    integer(i8), intent(in) :: gids(:)
    integer(i8), allocatable, intent(out) :: keys(:, :)
    integer, allocatable, intent(out) :: order(:)
    allocate (keys(1, size(gids)))
    keys(1, :) = gids
    call sort_index_keys(keys, order)
    keys = keys(:, order)
  end subroutine gid_index

end submodule simulation_cross_windows
