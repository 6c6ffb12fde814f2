!> The domain decomposition of a run (docs/architecture.md, "Domain decomposition in a run"):
!> the bricks and owners at the start, the window rule, and the migration at a window's end.
submodule (simulation) simulation_windows
  implicit none

contains

  module procedure decompose
    real(dp) :: lower(3), upper(3), r, h
    integer(i8) :: n_boxes(3)
    integer :: dims(3), i
    type(error_t) :: why
    h = self%collisions%box_size
    if (present(box)) h = box
    lower = huge(1.0_dp)
    upper = -huge(1.0_dp)
    do i = 1, everyone%n_owned
      r = self%shapes%shapes(everyone%shape_id(i))%bounding_radius
      lower = min(lower, everyone%x(:, i) - r)
      upper = max(upper, everyone%x(:, i) + r)
    end do
    n_boxes = int(floor(upper/h) - floor(lower/h), i8) + 1
    call suggest_dims(par%n_ranks, self%deck%parallel%dims, dims, why, n_boxes)
    if (why%ok()) call self%dom%init(h, lower, upper, dims, par%rank, why)
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
        str(self%dom%n_boxes(3))//' grid boxes of '//str(h, '(es10.3)')//' m'
      flush (output_unit)
    end if
  end procedure decompose

  module procedure take_brick
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
  end procedure take_brick

  module procedure motion_window
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
  end procedure motion_window

  module procedure migrate_owned
    integer(i8), allocatable :: payload(:, :)
    integer, allocatable :: leavers(:)
    integer :: i, k, n_old_owned
    n_old_owned = self%bodies%n_owned
    leavers = pack([(i, i=1, n_old_owned)], [(self%dom%owner_of(self%bodies%x(:, i)) /= self%dom%rank, &
                                               i=1, n_old_owned)])
    call self%propagator%pack_anchors(0, payload, leavers)
    call migrate_bodies(par, self%dom, self%bodies, err, versions=versions, new_index=new_index, &
                        stats=self%migration, payload=payload, payload_rows=leavers)
    if (err%failed()) return
    call self%propagator%remap(new_index(1:n_old_owned), self%bodies%n_owned)
    do k = 1, size(leavers)
      call self%propagator%set_record(leavers(k), payload(:, k))
    end do
  end procedure migrate_owned

  module procedure end_window
    integer(i8), allocatable :: versions(:)
    integer, allocatable :: new_index(:)
    integer :: i
    logical :: rebuilt
    real(dp) :: clock, loop_clock
    integer(i8) :: certificates_before
    clock = par%wtime()
    ! every body where it is now: it goes to the owner of its position at the window's end
    if (self%local) call self%events%synchronize(self%bodies, self%propagator, self%time)
    ! (the trajectory versions travel with the bodies: the local loop keeps its certificates)
    if (self%local) then
      versions = self%events%version(1:self%bodies%n_owned)
      call migrate_owned(self, par, new_index, err, versions)
    else
      call migrate_owned(self, par, new_index, err)
    end if
    if (par%any(err%failed())) then
      if (err%ok()) call err%set(ERR_INTERNAL, 'migration failed on another rank')
      return
    end if
    self%windows = self%windows + 1
    if (self%local) then
      loop_clock = par%wtime()
      certificates_before = self%events%stats%certificates
      do i = 1, self%bodies%n_owned
        if (.not. self%bodies%fixed(i) .and. self%propagator%is_anchored(i)) &
          call self%propagator%evaluate(self%bodies, i, self%time, self%deck%run%gravity)
      end do
      ! the loop follows the bodies: what stayed keeps its certificates, islands and queue
      ! entries, arrivals are placed and certified (event_loop%remap_bodies)
      call self%events%remap_bodies(self%collisions, self%bodies, self%shapes, self%propagator, new_index, versions, &
                                    self%time, min(self%deck%run%t_end, self%next_checkpoint), err, rebuilt)
      if (rebuilt) self%window_rebuilds = self%window_rebuilds + 1
      self%window_certificates = self%window_certificates + (self%events%stats%certificates - certificates_before)
      self%window_loop_wall = self%window_loop_wall + (par%wtime() - loop_clock)
      if (err%failed()) return
    end if
    self%window_end = self%time + motion_window(self, par)
    self%window_wall = self%window_wall + (par%wtime() - clock)
  end procedure end_window

end submodule simulation_windows
