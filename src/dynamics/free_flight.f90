!> Free flight of every owned body over one step, with the rotation method the deck chose:
!>  - 'newmark': Newmark with the iterative implicit correction (newmark_integrator), step by
!>    step;
!>  - 'exact': the closed-form motion between contacts. Each body is *anchored* at the state
!>    it had after its last change (start of the run, an impulse, a checkpoint) and its pose
!>    at time t is evaluated from the anchor: the centre of mass on the exact parabola, the
!>    orientation by the free rigid body's flow (free_rotation_exact). Nothing accumulates
!>    from step to step, so the error does not grow with the number of steps.
!> Anchors are re-taken at every checkpoint, so a run restarted from a checkpoint repeats the
!> same arithmetic as the run that wrote it (bitwise restarts).
module free_flight
  use kinds, only: dp, i8
  use input_config, only: integrator_config_t, ROTATION_EXACT
  use body_state, only: bodies_t
  use newmark_integrator, only: advance_free_flight, free_flight_stats_t, newmark_translate, newmark_rotate
  use free_rotation_exact, only: free_rotor_t
  implicit none
  private
  public :: free_flight_t

  type :: free_flight_t
    logical :: exact = .false.
    type(free_rotor_t), allocatable :: rotors(:)   !< exact mode: per body, from its anchor
    real(dp), allocatable :: t0(:)                 !< anchor time [s]
    real(dp), allocatable :: x0(:, :), v0(:, :)    !< centre of mass and its velocity at t0
    logical, allocatable :: anchored(:)
    !> Bodies held by resting contacts this step move with a constant acceleration other
    !> than gravity (gravity plus the contact force the contact solve found): accel(:, i).
    logical, allocatable :: loaded(:)
    real(dp), allocatable :: accel(:, :)           !< [m/s^2] where loaded
    !> An undo journal (a cross-rank window's save: docs/architecture.md, "Cross-rank
    !> contacts: windows with ghosts", step 4): while journaling, the first change of a body's record since start_journal
    !> keeps the record as it was (its anchor_words), and roll_back puts every such record
    !> back, bit for bit: O(records changed) instead of a copy of every record (40 MB of
    !> rotors for 50,000 bodies).
    logical :: journaling = .false.
    logical, allocatable :: journaled(:)
    integer :: n_journal = 0
    integer, allocatable :: journal_row(:)
    integer(i8), allocatable :: journal_words(:, :)
  contains
    procedure :: set_load => flight_set_load
    procedure :: clear_load => flight_clear_load
    procedure :: clear_all_loads => flight_clear_all_loads
    procedure :: acceleration => flight_acceleration
    procedure :: init => flight_init
    procedure :: release => flight_release
    procedure :: release_all => flight_release_all
    procedure :: advance => flight_advance
    procedure :: pose_at => flight_pose_at
    procedure :: anchor_at => flight_anchor_at
    procedure :: evaluate => flight_evaluate
    procedure :: is_anchored => flight_is_anchored
    procedure :: anchor_words => flight_anchor_words
    procedure :: pack_anchors => flight_pack_anchors
    procedure :: record_of => flight_record_of
    procedure :: set_record => flight_set_record
    procedure :: grow => flight_grow
    procedure :: remap => flight_remap
    procedure :: start_journal => flight_start_journal
    procedure :: stop_journal => flight_stop_journal
    procedure :: roll_back => flight_roll_back
  end type free_flight_t

contains

  subroutine flight_init(self, n_bodies, config, capacity)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: n_bodies
    type(integrator_config_t), intent(in) :: config
    !> rows to allocate if more than n_bodies: room for rows grow will add (a decomposed
    !> run's ghosts), which would otherwise reallocate and copy every record (~90 words
    !> each) into fresh pages
    integer, intent(in), optional :: capacity
    integer :: n_rows
    n_rows = n_bodies
    if (present(capacity)) n_rows = max(n_bodies, capacity)
    self%exact = config%rotation == ROTATION_EXACT
    self%journaling = .false.
    self%n_journal = 0
    if (allocated(self%journaled)) deallocate (self%journaled)
    if (allocated(self%loaded)) deallocate (self%loaded, self%accel)
    allocate (self%loaded(n_rows), self%accel(3, n_rows))
    self%loaded = .false.
    self%accel = 0.0_dp
    if (.not. self%exact) return
    if (allocated(self%rotors)) deallocate (self%rotors, self%t0, self%x0, self%v0, self%anchored)
    allocate (self%rotors(n_rows), self%t0(n_rows), self%x0(3, n_rows), self%v0(3, n_rows), &
              self%anchored(n_rows))
    self%anchored = .false.
    self%t0 = 0.0_dp
    self%x0 = 0.0_dp
    self%v0 = 0.0_dp
  end subroutine flight_init

  !> Body i's velocity or angular velocity changed (an impulse): re-anchor at its next step.
  subroutine flight_release(self, i)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: i
    if (.not. self%exact) return
    if (self%anchored(i)) call note(self, i)
    self%anchored(i) = .false.
  end subroutine flight_release

  !> Body i moves with the constant acceleration a [m/s^2] from now until the load changes.
  subroutine flight_set_load(self, i, a)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: i
    real(dp), intent(in) :: a(3)
    if (self%loaded(i)) then
      if (all(self%accel(:, i) == a)) return
    end if
    call note(self, i)
    self%loaded(i) = .true.
    self%accel(:, i) = a
    call self%release(i)
  end subroutine flight_set_load

  !> Body i is back under gravity alone.
  subroutine flight_clear_load(self, i)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: i
    if (.not. self%loaded(i)) return
    call note(self, i)
    self%loaded(i) = .false.
    call self%release(i)
  end subroutine flight_clear_load

  !> Every body back under gravity alone (checkpoints: a run restarted from one starts so).
  subroutine flight_clear_all_loads(self)
    class(free_flight_t), intent(inout) :: self
    integer :: i
    do i = 1, size(self%loaded)
      call self%clear_load(i)
    end do
  end subroutine flight_clear_all_loads

  !> The acceleration body i moves with [m/s^2].
  pure function flight_acceleration(self, i, gravity) result(a)
    class(free_flight_t), intent(in) :: self
    integer, intent(in) :: i
    real(dp), intent(in) :: gravity(3)
    real(dp) :: a(3)
    if (self%loaded(i)) then
      a = self%accel(:, i)
    else
      a = gravity
    end if
  end function flight_acceleration

  subroutine flight_release_all(self)
    class(free_flight_t), intent(inout) :: self
    integer :: i
    if (.not. self%exact) return
    if (self%journaling) then
      do i = 1, size(self%anchored)
        call self%release(i)
      end do
    end if
    self%anchored = .false.
  end subroutine flight_release_all

  !> Pose (x, q) body i will have after a step of tau from time_now, computed exactly as
  !> advance would compute it: what time of contact needs, so that the bound it uses holds
  !> for the motion the bodies really make. The body's state is not changed.
  !> omega, when present: the angular velocity then (world) [rad/s].
  subroutine flight_pose_at(self, bodies, i, time_now, tau, gravity, config, x, q, omega)
    class(free_flight_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: time_now, tau, gravity(3)
    type(integrator_config_t), intent(in) :: config
    real(dp), intent(out) :: x(3), q(4)
    real(dp), intent(out), optional :: omega(3)
    real(dp) :: v(3), a(3), w(3), alpha(3), dt
    integer :: iterations
    logical :: converged
    real(dp), parameter :: no_torque(3) = 0.0_dp
    if (bodies%fixed(i)) then
      x = bodies%x(:, i)
      q = bodies%q(:, i)
      if (present(omega)) omega = bodies%w(:, i)
      return
    end if
    if (self%exact) then
      if (.not. self%anchored(i)) call anchor(self, bodies, i, time_now)
      dt = (time_now + tau) - self%t0(i)
      x = self%x0(:, i) + self%v0(:, i)*dt + (0.5_dp*dt*dt)*self%acceleration(i, gravity)
      call self%rotors(i)%evaluate(dt, q, w)
      if (present(omega)) omega = w
    else
      x = bodies%x(:, i)
      v = bodies%v(:, i)
      a = self%acceleration(i, gravity)
      call newmark_translate(x, v, a, self%acceleration(i, gravity), tau, config%newmark_beta, config%newmark_gamma)
      q = bodies%q(:, i)
      w = bodies%w(:, i)
      alpha = bodies%alpha(:, i)
      call newmark_rotate(q, w, alpha, bodies%inertia(:, i), no_torque, tau, config%newmark_beta, &
                          config%newmark_gamma, config%rotation_tolerance, config%rotation_max_iterations, &
                          iterations, converged)
      if (present(omega)) omega = w
    end if
  end subroutine flight_pose_at

  !> Exact mode: body i's anchor is taken now, at time_now, from its state in bodies (the
  !> local event loop anchors a body as soon as its trajectory changes, instead of at its
  !> next step).
  subroutine flight_anchor_at(self, bodies, i, time_now)
    class(free_flight_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: time_now
    if (self%exact .and. .not. bodies%fixed(i)) call anchor(self, bodies, i, time_now)
  end subroutine flight_anchor_at

  !> Exact mode: is body i anchored (its trajectory known from its anchor)?
  pure logical function flight_is_anchored(self, i)
    class(free_flight_t), intent(in) :: self
    integer, intent(in) :: i
    flight_is_anchored = .false.
    if (self%exact) flight_is_anchored = self%anchored(i)
  end function flight_is_anchored

  !> Exact mode: body i's state at time t from its anchor, into bodies (x, q, v, w, a), by
  !> the same arithmetic as advance, so a body evaluated at t holds the state a step to t
  !> gives it.
  subroutine flight_evaluate(self, bodies, i, t, gravity)
    class(free_flight_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: t, gravity(3)
    real(dp) :: tau, a(3)
    tau = t - self%t0(i)
    a = self%acceleration(i, gravity)
    bodies%x(:, i) = self%x0(:, i) + self%v0(:, i)*tau + (0.5_dp*tau*tau)*a
    bodies%v(:, i) = self%v0(:, i) + tau*a
    bodies%a(:, i) = a
    call self%rotors(i)%evaluate(tau, bodies%q(:, i), bodies%w(:, i))
  end subroutine flight_evaluate

  !> Words (integer(i8)) of one body's flight record: what its trajectory is made of (load,
  !> and in exact mode the anchor: t0, x0, v0 and the whole rotor), so that a body
  !> migrating to another rank goes on bitwise as it would have here. The rotor travels as
  !> its bits, not as (q0, w0) to be set up again: rotor_init normalises q0, which is not
  !> idempotent to the last bit.
  pure integer function flight_anchor_words(self) result(n_words)
    class(free_flight_t), intent(in) :: self
    type(free_rotor_t) :: probe
    integer(i8), allocatable :: mold(:)
    n_words = 5      ! loaded, accel(3), anchored
    if (self%exact) then
      allocate (mold(0))
      n_words = n_words + 7 + size(transfer(probe, mold))
    end if
  end function flight_anchor_words

  !> words(:, k): the flight record of body k = 1..n (anchor_words rows), bit for bit.
  !> rows, when present: words(:, m) is the record of body rows(m) instead (n unused), so
  !> that a few bodies' records cost what they are (a light window start's changed ghosts,
  !> a cross phase's ghosts sent back), not O(bodies held).
  subroutine flight_pack_anchors(self, n, words, rows)
    class(free_flight_t), intent(in) :: self
    integer, intent(in) :: n
    integer(i8), allocatable, intent(out) :: words(:, :)
    integer, intent(in), optional :: rows(:)
    integer :: k, m, n_rows
    n_rows = n
    if (present(rows)) n_rows = size(rows)
    allocate (words(self%anchor_words(), n_rows))
    do m = 1, n_rows
      k = m
      if (present(rows)) k = rows(m)
      call pack_row(self, k, words(:, m))
    end do
  end subroutine flight_pack_anchors

  !> Body k's flight record as anchor_words words (one column of pack_anchors).
  subroutine flight_record_of(self, k, words)
    class(free_flight_t), intent(in) :: self
    integer, intent(in) :: k
    integer(i8), intent(out) :: words(:)
    call pack_row(self, k, words)
  end subroutine flight_record_of

  !> Body k's flight record as anchor_words words.
  subroutine pack_row(self, k, words)
    type(free_flight_t), intent(in) :: self
    integer, intent(in) :: k
    integer(i8), intent(out) :: words(:)
    integer(i8) :: mold(0)
    integer :: w
    w = size(words)
    words(1) = merge(1_i8, 0_i8, self%loaded(k))
    words(2:4) = transfer(self%accel(:, k), mold)
    words(5:) = 0
    if (.not. self%exact) return
    words(5) = merge(1_i8, 0_i8, self%anchored(k))
    words(6) = transfer(self%t0(k), 1_i8)
    words(7:9) = transfer(self%x0(:, k), mold)
    words(10:12) = transfer(self%v0(:, k), mold)
    words(13:w) = transfer(self%rotors(k), mold)
  end subroutine pack_row

  !> While journaling: body i's record is about to change; the first time since
  !> start_journal, it is kept as it is now.
  subroutine note(self, i)
    type(free_flight_t), intent(inout) :: self
    integer, intent(in) :: i
    integer, allocatable :: rows(:)
    integer(i8), allocatable :: words(:, :)
    integer :: n
    if (.not. self%journaling) return
    if (self%journaled(i)) return
    self%journaled(i) = .true.
    n = self%n_journal
    if (n == size(self%journal_row)) then
      allocate (rows(2*n), words(size(self%journal_words, 1), 2*n))
      rows(1:n) = self%journal_row(1:n)
      words(:, 1:n) = self%journal_words(:, 1:n)
      call move_alloc(rows, self%journal_row)
      call move_alloc(words, self%journal_words)
    end if
    n = n + 1
    self%n_journal = n
    self%journal_row(n) = i
    call pack_row(self, i, self%journal_words(:, n))
  end subroutine note

  !> From now on the first change of each record is kept, until roll_back or stop_journal
  !> (the records of bodies 1..size(loaded) as they are now: the state roll_back returns to).
  subroutine flight_start_journal(self)
    class(free_flight_t), intent(inout) :: self
    integer :: m
    if (.not. allocated(self%loaded)) return
    if (allocated(self%journaled)) then
      if (size(self%journaled) /= size(self%loaded)) deallocate (self%journaled)
    end if
    if (.not. allocated(self%journaled)) then
      allocate (self%journaled(size(self%loaded)))
      self%journaled = .false.
    else
      do m = 1, self%n_journal
        self%journaled(self%journal_row(m)) = .false.
      end do
    end if
    if (allocated(self%journal_words)) then
      ! (a record's width follows the mode: exact records carry the rotor)
      if (size(self%journal_words, 1) /= self%anchor_words()) deallocate (self%journal_row, self%journal_words)
    end if
    if (.not. allocated(self%journal_row)) allocate (self%journal_row(64), self%journal_words(self%anchor_words(), 64))
    self%n_journal = 0
    self%journaling = .true.
  end subroutine flight_start_journal

  !> No more journal (the records kept are dropped).
  subroutine flight_stop_journal(self)
    class(free_flight_t), intent(inout) :: self
    integer :: m
    if (self%journaling) then
      do m = 1, self%n_journal
        self%journaled(self%journal_row(m)) = .false.
      end do
    end if
    self%n_journal = 0
    self%journaling = .false.
  end subroutine flight_stop_journal

  !> Every record changed since start_journal back as it was then, bit for bit; the journal
  !> goes on from there (a later roll_back returns to the same state).
  subroutine flight_roll_back(self)
    class(free_flight_t), intent(inout) :: self
    integer :: m
    if (.not. self%journaling) return
    self%journaling = .false.
    do m = self%n_journal, 1, -1
      call self%set_record(self%journal_row(m), self%journal_words(:, m))
      self%journaled(self%journal_row(m)) = .false.
    end do
    self%n_journal = 0
    self%journaling = .true.
  end subroutine flight_roll_back

  !> Room for bodies up to n, the records held kept (rows appended: ghosts that arrive at a
  !> light window start). New rows: no load, not anchored.
  subroutine flight_grow(self, n)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: n
    type(free_rotor_t), allocatable :: rotors(:)
    real(dp), allocatable :: t0(:), x0(:, :), v0(:, :), accel(:, :)
    logical, allocatable :: anchored(:), loaded(:), journaled(:)
    integer :: old, n_rows
    if (.not. allocated(self%loaded)) return
    old = size(self%loaded)
    if (old >= n) return
    ! (room for a quarter more: a cross-rank window's start appends a few ghost rows at a
    ! time, and growing to the exact count copied every record each time, 0.2 s over the
    ! light starts of a 100,000-sphere gas on two ranks)
    n_rows = max(n, old + old/4)
    allocate (loaded(n_rows), accel(3, n_rows))
    loaded(1:old) = self%loaded
    loaded(old + 1:) = .false.
    accel(:, 1:old) = self%accel
    accel(:, old + 1:) = 0.0_dp
    call move_alloc(loaded, self%loaded)
    call move_alloc(accel, self%accel)
    if (allocated(self%journaled)) then
      allocate (journaled(n_rows))
      journaled(1:old) = self%journaled
      journaled(old + 1:) = .false.
      call move_alloc(journaled, self%journaled)
    end if
    if (.not. self%exact) return
    allocate (rotors(n_rows), t0(n_rows), x0(3, n_rows), v0(3, n_rows), anchored(n_rows))
    rotors(1:old) = self%rotors
    t0(1:old) = self%t0
    x0(:, 1:old) = self%x0
    v0(:, 1:old) = self%v0
    anchored(1:old) = self%anchored
    anchored(old + 1:) = .false.
    t0(old + 1:) = 0.0_dp
    x0(:, old + 1:) = 0.0_dp
    v0(:, old + 1:) = 0.0_dp
    call move_alloc(rotors, self%rotors)
    call move_alloc(t0, self%t0)
    call move_alloc(x0, self%x0)
    call move_alloc(v0, self%v0)
    call move_alloc(anchored, self%anchored)
  end subroutine flight_grow

  !> The rows were renumbered (a migration): row k's record goes to row new_index(k) (0: it
  !> is gone), in room for n rows; rows no record came to have no load and no anchor (the
  !> caller sets those of the bodies that arrived: set_record). One gather of each array,
  !> where packing every record and unpacking them again copied them four times (36 MB for
  !> 50,000 bodies, at every full window start). Not while journaling.
  subroutine flight_remap(self, new_index, n)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n
    type(free_rotor_t), allocatable :: rotors(:)
    real(dp), allocatable :: t0(:), x0(:, :), v0(:, :), accel(:, :)
    logical, allocatable :: anchored(:), loaded(:)
    integer :: k, nk, n_old
    if (.not. allocated(self%loaded)) return
    n_old = min(size(new_index), size(self%loaded))
    if (allocated(self%journaled)) deallocate (self%journaled)
    self%journaling = .false.
    self%n_journal = 0
    allocate (loaded(n), accel(3, n))
    loaded = .false.
    accel = 0.0_dp
    do k = 1, n_old
      nk = new_index(k)
      if (nk < 1 .or. nk > n) cycle
      loaded(nk) = self%loaded(k)
      accel(:, nk) = self%accel(:, k)
    end do
    call move_alloc(loaded, self%loaded)
    call move_alloc(accel, self%accel)
    if (.not. self%exact) return
    allocate (rotors(n), t0(n), x0(3, n), v0(3, n), anchored(n))
    anchored = .false.
    t0 = 0.0_dp
    x0 = 0.0_dp
    v0 = 0.0_dp
    do k = 1, n_old
      nk = new_index(k)
      if (nk < 1 .or. nk > n) cycle
      rotors(nk) = self%rotors(k)
      t0(nk) = self%t0(k)
      x0(:, nk) = self%x0(:, k)
      v0(:, nk) = self%v0(:, k)
      anchored(nk) = self%anchored(k)
    end do
    call move_alloc(rotors, self%rotors)
    call move_alloc(t0, self%t0)
    call move_alloc(x0, self%x0)
    call move_alloc(v0, self%v0)
    call move_alloc(anchored, self%anchored)
  end subroutine flight_remap

  !> Body i's flight record from words (one record of pack_anchors), bit for bit: a body
  !> whose new trajectory another rank computed (a cross-rank impact).
  subroutine flight_set_record(self, i, words)
    class(free_flight_t), intent(inout) :: self
    integer, intent(in) :: i
    integer(i8), intent(in) :: words(:)
    type(free_rotor_t) :: probe
    integer :: w
    call note(self, i)
    w = size(words)
    self%loaded(i) = words(1) /= 0
    self%accel(:, i) = transfer(words(2:4), self%accel(:, i))
    if (.not. self%exact) return
    self%anchored(i) = words(5) /= 0
    self%t0(i) = transfer(words(6), self%t0(i))
    self%x0(:, i) = transfer(words(7:9), self%x0(:, i))
    self%v0(:, i) = transfer(words(10:12), self%v0(:, i))
    self%rotors(i) = transfer(words(13:w), probe)
  end subroutine flight_set_record

  subroutine anchor(self, bodies, i, time_now)
    type(free_flight_t), intent(inout) :: self
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: i
    real(dp), intent(in) :: time_now
    call note(self, i)
    call self%rotors(i)%init(bodies%inertia(:, i), bodies%q(:, i), bodies%w(:, i))
    self%t0(i) = time_now
    self%x0(:, i) = bodies%x(:, i)
    self%v0(:, i) = bodies%v(:, i)
    self%anchored(i) = .true.
  end subroutine anchor

  !> Moves every owned body from time_old to time_new = time_old + h.
  subroutine flight_advance(self, bodies, time_old, time_new, h, gravity, config, stats)
    class(free_flight_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    real(dp), intent(in) :: time_old, time_new   !< [s]
    real(dp), intent(in) :: h                    !< time_new - time_old as the step uses it [s]
    real(dp), intent(in) :: gravity(3)           !< [m/s^2]
    type(integrator_config_t), intent(in) :: config
    type(free_flight_stats_t), intent(inout) :: stats
    integer :: i
    if (.not. self%exact) then
      ! The acceleration is constant over the step (gravity, or gravity plus a resting
      ! contact's force), so Newmark's start and end accelerations are the same.
      do i = 1, bodies%n_owned
        if (.not. bodies%fixed(i)) bodies%a(:, i) = self%acceleration(i, gravity)
      end do
      call advance_free_flight(bodies, h, gravity, config, stats, acceleration=(bodies%a))
      return
    end if
    do i = 1, bodies%n_owned
      if (bodies%fixed(i)) cycle
      if (.not. self%anchored(i)) call anchor(self, bodies, i, time_old)
      call self%evaluate(bodies, i, time_new, gravity)
      stats%rotation_updates = stats%rotation_updates + 1
    end do
  end subroutine flight_advance

end module free_flight
