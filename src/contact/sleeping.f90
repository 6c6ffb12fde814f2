!> Sleeping: a scene pays for what moves (docs/contact.md, "Sleeping").
!>
!> An island is a set of moving bodies joined by contacts in the contact band (static bodies
!> do not join islands). When every body of an island has stayed quiet, |v| < sleep_speed
!> and |w| R < sleep_speed (R its bounding radius: the fastest any of its points turns),
!> for sleep_time, the whole island falls asleep: velocities are set to zero and its
!> bodies are held like static ones (fixed, inverse mass and inertia 0), so the propagator,
!> the time of contact and the contact solvers skip them and their pairs with each other
!> cost nothing. An island wakes, whole, as soon as a moving body reaches the contact band
!> of any of its bodies (the contact pass and the impacts call wake_touching), and every
!> island wakes at a checkpoint, so that a restarted run continues exactly as the
!> uninterrupted one (both see every body awake with its quiet time reset there).
!>
!> Islands sleep together because a body in a resting stack carries the load of the ones
!> above: freezing one member alone would turn it into a support that cannot give way.
module sleeping
  use kinds, only: dp, i8
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use shape, only: shape_library_t
  use impulse_solver, only: contact_t, find_root, unite
  implicit none
  private
  public :: sleep_t

  type :: sleep_t
    real(dp) :: speed = 0.0_dp               !< quiet below this speed of any point [m/s]; 0: never sleep
    real(dp) :: time = 0.5_dp                !< quiet for this long before sleeping [s]
    real(dp), allocatable :: quiet(:)        !< how long each body has been quiet [s]
    integer(i8), allocatable :: island(:)    !< asleep: an id shared by its island; awake: 0
    real(dp), allocatable :: inv_mass(:)     !< awake inverse mass of an asleep body [1/kg]
    real(dp), allocatable :: inv_inertia(:, :) !< awake inverse principal moments [1/(kg m^2)]
    integer :: n_asleep = 0                  !< bodies asleep now
    integer :: n_asleep_at_wake_all = 0      !< bodies asleep when wake_all was last called
    integer(i8) :: sleeps = 0                !< bodies put to sleep, so far
    integer(i8) :: wakes = 0                 !< bodies woken, so far
  contains
    procedure :: init => sleep_init
    procedure :: enabled => sleep_enabled
    procedure :: update => sleep_update
    procedure :: wake_touching => sleep_wake_touching
    procedure :: wake_all => sleep_wake_all
  end type sleep_t

contains

  !> n: bodies held (owned and ghosts); speed [m/s] (0 disables), time [s].
  subroutine sleep_init(self, n, speed, time)
    class(sleep_t), intent(inout) :: self
    integer, intent(in) :: n
    real(dp), intent(in) :: speed, time
    self%speed = speed
    self%time = time
    if (allocated(self%quiet)) deallocate (self%quiet, self%island, self%inv_mass, self%inv_inertia)
    allocate (self%quiet(n), self%island(n), self%inv_mass(n), self%inv_inertia(3, n))
    self%quiet = 0.0_dp
    self%island = 0
    self%inv_mass = 0.0_dp
    self%inv_inertia = 0.0_dp
    self%n_asleep = 0
  end subroutine sleep_init

  pure logical function sleep_enabled(self)
    class(sleep_t), intent(in) :: self
    sleep_enabled = self%speed > 0.0_dp
  end function sleep_enabled

  !> After a step of h [s]: quiet times, then islands (joined by the pairs(:, 1:n_pairs)
  !> found in the contact band) whose every body has been quiet for sleep_time fall asleep.
  subroutine sleep_update(self, bodies, shapes, flight, h, pairs, n_pairs)
    class(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h
    integer, intent(in) :: pairs(:, :), n_pairs
    integer, allocatable :: parent(:)
    real(dp), allocatable :: island_quiet(:)
    real(dp) :: reach
    integer :: n, i, k, root
    if (.not. self%enabled()) return
    n = bodies%n_owned
    do i = 1, n
      if (bodies%fixed(i)) cycle
      reach = shapes%shapes(bodies%shape_id(i))%bounding_radius
      if (norm2(bodies%v(:, i)) < self%speed .and. norm2(bodies%w(:, i))*reach < self%speed) then
        self%quiet(i) = self%quiet(i) + h
      else
        self%quiet(i) = 0.0_dp
      end if
    end do
    if (.not. any(self%quiet(1:n) >= self%time .and. .not. bodies%fixed(1:n))) return
    ! Islands: moving bodies joined by band contacts; an island sleeps on its least quiet body.
    allocate (parent(n), island_quiet(n))
    parent = [(i, i=1, n)]
    do k = 1, n_pairs
      if (pairs(1, k) > n .or. pairs(2, k) > n) cycle
      if (bodies%fixed(pairs(1, k)) .or. bodies%fixed(pairs(2, k))) cycle
      call unite(parent, pairs(1, k), pairs(2, k))
    end do
    island_quiet = huge(1.0_dp)
    do i = 1, n
      if (bodies%fixed(i)) cycle
      root = find_root(parent, i)
      island_quiet(root) = min(island_quiet(root), self%quiet(i))
    end do
    do i = 1, n
      if (bodies%fixed(i)) cycle
      root = find_root(parent, i)
      if (island_quiet(root) < self%time) cycle
      ! The island's id: its root body's global id, unique among islands asleep at once.
      self%island(i) = bodies%gid(root)
      self%inv_mass(i) = bodies%inv_mass(i)
      self%inv_inertia(:, i) = bodies%inv_inertia(:, i)
      bodies%asleep(i) = .true.
      bodies%fixed(i) = .true.
      bodies%inv_mass(i) = 0.0_dp
      bodies%inv_inertia(:, i) = 0.0_dp
      bodies%v(:, i) = 0.0_dp
      bodies%w(:, i) = 0.0_dp
      bodies%a(:, i) = 0.0_dp
      bodies%alpha(:, i) = 0.0_dp
      call flight%clear_load(i)
      call flight%release(i)
      self%n_asleep = self%n_asleep + 1
      self%sleeps = self%sleeps + 1
    end do
  end subroutine sleep_update

  !> Wakes every island that one of contacts(:) joins to a moving body; woke tells whether
  !> any did (the caller then gathers the contacts again: the woken bodies' contacts with
  !> each other were skipped while they were asleep).
  subroutine sleep_wake_touching(self, bodies, flight, contacts, woke)
    class(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    type(contact_t), intent(in) :: contacts(:)
    logical, intent(out) :: woke
    integer :: c, a, b
    woke = .false.
    if (self%n_asleep == 0) return
    do c = 1, size(contacts)
      a = contacts(c)%a
      b = contacts(c)%b
      if (bodies%asleep(a) .and. .not. bodies%fixed(b)) then
        call wake_island(self, bodies, flight, self%island(a))
        woke = .true.
      else if (bodies%asleep(b) .and. .not. bodies%fixed(a)) then
        call wake_island(self, bodies, flight, self%island(b))
        woke = .true.
      end if
    end do
  end subroutine sleep_wake_touching

  !> Wakes every body (checkpoints) and resets every quiet time.
  subroutine sleep_wake_all(self, bodies, flight)
    class(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer :: i
    if (.not. allocated(self%quiet)) return
    self%n_asleep_at_wake_all = self%n_asleep
    do i = 1, bodies%n_owned
      if (bodies%asleep(i)) call wake_body(self, bodies, flight, i)
    end do
    self%quiet = 0.0_dp
  end subroutine sleep_wake_all

  subroutine wake_island(self, bodies, flight, id)
    type(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer(i8), intent(in) :: id
    integer :: i
    do i = 1, bodies%n_owned
      if (bodies%asleep(i) .and. self%island(i) == id) call wake_body(self, bodies, flight, i)
    end do
  end subroutine wake_island

  subroutine wake_body(self, bodies, flight, i)
    type(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    bodies%asleep(i) = .false.
    bodies%fixed(i) = .false.
    bodies%inv_mass(i) = self%inv_mass(i)
    bodies%inv_inertia(:, i) = self%inv_inertia(:, i)
    self%island(i) = 0
    self%quiet(i) = 0.0_dp
    call flight%release(i)
    self%n_asleep = self%n_asleep - 1
    self%wakes = self%wakes + 1
  end subroutine wake_body

end module sleeping
