!> What a run writes: history rows with their conservation errors, frames, checkpoints and
!> their metadata, and the end-of-run summary.
submodule (simulation) simulation_output
  implicit none

contains

  module procedure record_history
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
  end procedure record_history

  module procedure write_frame
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
  end procedure write_frame

  module procedure write_checkpoint_now
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
    ! (the effective deck's lines lent to the writer, not copied: 20 lines a body, 51 MB for
    ! 27,000 spheres, copied at every checkpoint before)
    call move_alloc(self%deck_lines, meta%deck_lines)
    if (par%n_ranks > 1) then
      ! in global-id blocks: the same file on any number of ranks, whoever owned which body
      call gather_gid_blocks(par, self%bodies, self%n_total, blocks, err)
      if (par%any(err%failed())) then
        if (err%ok()) call err%set(ERR_INTERNAL, "checkpoint '"//name//"': another rank could not take its bodies")
      else
        call write_checkpoint(par, join_path(self%output_dir, name//'.h5'), meta, blocks, err)
      end if
    else
      call write_checkpoint(par, join_path(self%output_dir, name//'.h5'), meta, self%bodies, err)
    end if
    call move_alloc(meta%deck_lines, self%deck_lines)
    if (err%failed()) return
    ! Exact flight re-anchors at the checkpoint's state, as a run restarted from it will, and
    ! no body carries the contact pass's load into the next step (the candidate pairs of a
    ! step's start depend on it: a restart has none).
    call self%propagator%clear_all_loads()
    call self%propagator%release_all()
    call self%collisions%resting%forget()
  end procedure write_checkpoint_now

  module procedure fill_meta
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
    meta%counter_names = [character(len=name_length) :: 'initial_kinetic_translational', &
                          'initial_kinetic_rotational', 'initial_potential', 'max_energy_error', &
                          'max_momentum_error', 'max_angular_momentum_error', 'events', 'contacts', &
                          'advancement_iterations', 'pair_tests', 'min_separation']
    meta%counters = [self%initial%kinetic_translational, self%initial%kinetic_rotational, self%initial%potential, &
                     self%max_energy_error, self%max_momentum_error, self%max_angular_momentum_error, &
                     real(par%sum(self%collisions%stats%events), dp), &
                     real(par%sum(self%collisions%stats%contacts), dp), &
                     real(par%sum(self%collisions%stats%advancement_iterations), dp), &
                     real(par%sum(self%collisions%stats%pair_tests), dp), par%min(self%collisions%stats%min_separation)]
  end procedure fill_meta

  module procedure simulation_summary
    real(dp) :: wall, per_step, min_sep, load(3, 3), startup, window_wall, window_loop_wall
    integer(i8) :: events, contacts, pair_tests, migrated, bytes, messages, window_certificates, window_rebuilds
    integer(i8) :: convex_bounds, cross_count(6), deferred, cross_impacts
    real(dp) :: cross_wall(2), rate, phases(N_STARTUP_PHASES)
    character(len=:), allocatable :: line
    integer :: k
    wall = par%wtime() - self%wall_start
    ! The load of each rank (min, mean, max over ranks): bodies owned at the end, events, busy
    ! time (the rank's own work on events and outputs, without the windows' starts and the
    ! waits in collectives).
    load(:, 1) = real(self%bodies%n_owned, dp)
    load(:, 2) = real(self%collisions%stats%events + self%events%stats%island_steps, dp)
    if (self%local) then
      ! (the local loop times its phases itself)
      load(:, 3) = self%events%stats%wall_islands + self%events%stats%wall_impacts + self%events%stats%wall_detection + &
                   self%integration_wall
    else
      load(:, 3) = self%detection_wall + self%integration_wall + self%contact_pass_wall + self%resolve_wall
    end if
    load(1, :) = [par%min(load(1, 1)), par%min(load(1, 2)), par%min(load(1, 3))]
    load(2, :) = [par%sum(load(2, 1)), par%sum(load(2, 2)), par%sum(load(2, 3))]/real(par%n_ranks, dp)
    load(3, :) = [par%max(load(3, 1)), par%max(load(3, 2)), par%max(load(3, 3))]
    migrated = par%sum(self%migration%bodies_left)
    bytes = par%sum(self%migration%bytes_sent)
    messages = par%sum(self%migration%messages_sent)
    window_wall = par%max(self%window_wall)
    window_loop_wall = par%max(self%window_loop_wall)
    window_certificates = par%sum(self%window_certificates)
    window_rebuilds = par%sum(self%window_rebuilds)
    cross_count(1:3) = self%cross_count(1:3)
    cross_count(4) = par%sum(self%cross_count(4))
    cross_count(5) = self%cross_count(5)
    cross_count(6) = par%sum(self%cross_count(6))
    cross_impacts = par%sum(self%events%stats%cross_impacts)
    cross_wall = [par%max(self%cross_wall(1)), par%max(self%cross_wall(2))]
    deferred = par%sum(self%events%deferred)
    ! Over every rank (collective, before rank 0 alone goes on to print).
    events = par%sum(self%collisions%stats%events)
    contacts = par%sum(self%collisions%stats%contacts)
    pair_tests = par%sum(self%collisions%stats%pair_tests)
    convex_bounds = par%sum(self%collisions%stats%convex_bounds)
    min_sep = par%min(self%collisions%stats%min_separation)
    startup = par%max(self%startup_wall)
    do k = 1, N_STARTUP_PHASES
      phases(k) = par%max(self%startup_phases(k))
    end do
    if (.not. par%is_root()) return
    per_step = wall/max(real(self%step - self%first_step, dp), 1.0_dp)
    write (*, '(a)') 'ricochet: run finished at t = '//str(self%time, '(g0.6)')//' s'
    write (*, '(a,es10.3,a,i0,a,i0,a)') '  wall time            ', wall, ' s on ', par%n_ranks, ' rank(s), ', &
      self%step - self%first_step, ' steps in this run'
    ! (what the domain decomposition leaves O(all bodies) per rank sits here: docs/architecture.md)
    line = '  start-up             '//str(startup, '(es10.3)')//' s (slowest rank), of which'
    do k = 1, N_STARTUP_PHASES
      line = line//' '//trim(STARTUP_PHASE_NAMES(k))//' '//str(phases(k), '(es9.3)')// &
             trim(merge(', ', ' s', k < N_STARTUP_PHASES))
    end do
    write (*, '(a)') line
    write (*, '(a,es10.3,a,es10.3,a)') '  time per step        ', per_step, ' s (', &
      per_step/max(real(self%n_total, dp), 1.0_dp), ' s per body)'
    ! (no time measured, no rate: 0)
    rate = 0.0_dp
    if (self%integration_wall > 1.0e-9_dp) &
      rate = real(self%n_total, dp)*real(self%step - self%first_step, dp)/self%integration_wall
    write (*, '(a,es10.3,a,es10.3,a)') '  integration time     ', self%integration_wall, ' s (', rate, &
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
      if (self%cross_windows) then
        write (*, '(a)') '  cross-rank windows   '//str(cross_count(1))//' ('//str(cross_count(2))//' run again to '// &
          'an earlier time, '//str(cross_count(3))//' of them ending in a cross phase (at a cross-rank impact '// &
          'or a halo stop known ahead), '//str(cross_count(4))// &
          ' ghosts sent back to their owners, '//str(cross_count(5))//' started light: only changed ghosts sent, and '//str(cross_count(6))//' bodies that came near a '// &
          'neighbouring brick); '// &
          str(migrated)//' bodies changed rank, '//str(messages)// &
          ' messages, '//str(bytes)//' bytes'
        write (*, '(a)') '  window costs         '//str(cross_wall(1), '(es9.3)')//' s starting windows (migration, '// &
          'halo, loop built; or the changed ghosts), '//str(cross_wall(2), '(es9.3)')//' s in runs repeated to an earlier time (slowest rank); '// &
          str(deferred)//' cross-rank impacts left to the next window (a ghost in their group was stale)'
        write (*, '(a)') '  cross-rank impacts   '//str(cross_impacts)//' taken by both ranks in the windows'' runs '// &
          '(their change logs agreed at the window''s end)'
      else if (self%decomposed) then
        write (*, '(a)') '  windows              '//str(self%windows)//' ended by a migration: '//str(migrated)// &
          ' bodies changed rank, '//str(messages)//' messages, '//str(bytes)//' bytes'
        ! (the slowest rank's times: the others wait for it at the next collective)
        write (*, '(a)') '  window ends          '//str(window_wall, '(es9.3)')//' s (slowest rank; of it the '// &
          'local loop brought up to date '//str(window_loop_wall, '(es9.3)')//' s), '//str(window_certificates)// &
          ' pair certificates computed there (all ranks), '//str(window_rebuilds)// &
          ' loops built again for an island split between ranks'
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
          ' bodies waited to join, '//str(ev%holds)//' held to repeated impacts), '//str(ev%enters)// &
          ' pairs came within reach of a pass'
        write (*, '(a)') '  pair certificates    '//str(ev%certificates)//' ('//str(ev%far_certificates)// &
          ' from bounding volumes), '//str(ev%crossings)//' box crossings'
        write (*, '(a)') '  body updates         '//str(ev%evaluations)//' for events, '//str(ev%output_evaluations)// &
          ' for outputs, '//str(ev%trajectory_changes)//' trajectory changes; '// &
          str(self%events%bodies_unchanged(self%bodies))//' bodies never changed trajectory'
      end associate
    end if
    write (*, '(a,i0,a,i0,a,i0,a)') '  time of contact      ', pair_tests, ' pair queries, ', &
      self%collisions%stats%advancement_iterations, ' advancement iterations (', self%collisions%stats%capped, &
      ' capped, '//str(self%collisions%stats%plane_skips)//' started from a second-order safe time), '// &
      str(convex_bounds)//' GJK bounds in place of queries'
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
        if (rest%stats%turning_repairs > 0) write (*, '(a)') '  turning term         '// &
          str(rest%stats%turning_repairs)//' group-steps projected again for their turning ('// &
          str(rest%stats%turning_rounds)//' projections, '//str(rest%stats%turning_left)//' still short after the last)'
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
  end procedure simulation_summary

end submodule simulation_output
