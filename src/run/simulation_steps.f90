!> The run's loop, in both event loops: the step or the local events up to each output or
!> window end, the outputs due there, progress lines, and stops on a signal or the wall limit.
submodule (simulation) simulation_steps
  implicit none

contains

  module procedure simulation_run
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
  end procedure simulation_run

  module procedure run_local
    real(dp) :: t_end, t_stop, t_hard, clock, t_output
    logical :: checkpointed, window_ends
    integer(i8) :: events_before
    if (self%cross_windows) then
      call run_cross_windows(self, par, err)
      return
    end if
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
  end procedure run_local

  module procedure stop_if_requested
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
  end procedure stop_if_requested

  module procedure write_due_outputs
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
  end procedure write_due_outputs

  module procedure write_events
    character(len=:), allocatable :: name
    if (.not. self%collisions%log_events) return
    name = 'events.csv'
    if (par%n_ranks > 1) name = 'events_rank'//str(par%rank)//'.csv'
    if (.not. allocated(self%collisions%log_rows)) allocate (self%collisions%log_rows(8, 0))
    call write_event_log(join_path(self%output_dir, name), self%collisions%log_rows, self%collisions%n_log, err)
  end procedure write_events

  module procedure progress
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
  end procedure progress

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

end submodule simulation_steps
