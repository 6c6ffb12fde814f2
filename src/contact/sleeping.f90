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
  use impulse_solver, only: contact_t
  use islands, only: body_islands
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
    procedure :: wake_island_of => sleep_wake_island_of
    procedure :: wake_all => sleep_wake_all
    procedure :: remap_bodies => sleep_remap_bodies
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

  !> The bodies were renumbered (a migration): body i is now new_index(i), 0 if it left, of
  !> n bodies. Bodies that stayed keep their quiet times and sleeping islands; arrivals start
  !> awake and quiet for no time (as at a restart). (An asleep body does not move, so it does
  !> not change rank: every asleep body stays.)
  subroutine sleep_remap_bodies(self, new_index, n)
    class(sleep_t), intent(inout) :: self
    integer, intent(in) :: new_index(:)
    integer, intent(in) :: n
    real(dp), allocatable :: quiet(:), inv_mass(:), inv_inertia(:, :)
    integer(i8), allocatable :: island(:)
    integer :: i, ni
    if (.not. allocated(self%quiet)) return
    allocate (quiet(n), island(n), inv_mass(n), inv_inertia(3, n))
    quiet = 0.0_dp
    island = 0
    inv_mass = 0.0_dp
    inv_inertia = 0.0_dp
    do i = 1, min(size(new_index), size(self%quiet))
      ni = new_index(i)
      if (ni == 0) cycle
      quiet(ni) = self%quiet(i)
      island(ni) = self%island(i)
      inv_mass(ni) = self%inv_mass(i)
      inv_inertia(:, ni) = self%inv_inertia(:, i)
    end do
    call move_alloc(quiet, self%quiet)
    call move_alloc(island, self%island)
    call move_alloc(inv_mass, self%inv_mass)
    call move_alloc(inv_inertia, self%inv_inertia)
  end subroutine sleep_remap_bodies

  pure logical function sleep_enabled(self)
    class(sleep_t), intent(in) :: self
    sleep_enabled = self%speed > 0.0_dp
  end function sleep_enabled

  !> After a step of h [s]: quiet times, then islands (joined by the pairs(:, 1:n_pairs)
  !> found in the contact band) whose every body has been quiet for sleep_time fall asleep.
  !> members, when present: the bodies that stepped (an island of the local event loop);
  !> default: every owned body. The cost is that of the members and pairs.
  !> asleep_now, when present: the bodies this call put to sleep.
  subroutine sleep_update(self, bodies, shapes, flight, h, pairs, n_pairs, members, asleep_now, n_asleep_now)
    class(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(shape_library_t), intent(in) :: shapes
    type(free_flight_t), intent(inout) :: flight
    real(dp), intent(in) :: h
    integer, intent(in) :: pairs(:, :), n_pairs
    integer, intent(in), optional :: members(:)
    integer, allocatable, intent(inout), optional :: asleep_now(:)
    integer, intent(out), optional :: n_asleep_now
    integer, allocatable :: list(:), label(:), root(:)
    real(dp), allocatable :: island_quiet(:)
    real(dp) :: reach
    integer :: n, i, m, k, n_list, n_components
    logical :: any_quiet
    if (present(n_asleep_now)) n_asleep_now = 0
    if (.not. self%enabled()) return
    ! the moving bodies concerned, in increasing index
    if (present(members)) then
      list = pack(members, members <= bodies%n_owned)
    else
      list = [(i, i=1, bodies%n_owned)]
    end if
    list = pack(list, .not. bodies%fixed(list))
    n_list = size(list)
    any_quiet = .false.
    do m = 1, n_list
      i = list(m)
      reach = shapes%shapes(bodies%shape_id(i))%bounding_radius
      if (norm2(bodies%v(:, i)) < self%speed .and. norm2(bodies%w(:, i))*reach < self%speed) then
        self%quiet(i) = self%quiet(i) + h
      else
        self%quiet(i) = 0.0_dp
      end if
      if (self%quiet(i) >= self%time) any_quiet = .true.
    end do
    if (.not. any_quiet) return
    ! Islands: moving bodies joined by band contacts; an island sleeps on its least quiet body.
    call body_islands(list, n_list, pairs, n_pairs, label, n_components)
    allocate (island_quiet(n_components), root(n_components))
    island_quiet = huge(1.0_dp)
    root = 0
    do m = 1, n_list
      k = label(m)
      if (root(k) == 0) root(k) = list(m)
      island_quiet(k) = min(island_quiet(k), self%quiet(list(m)))
    end do
    n = 0
    do m = 1, n_list
      i = list(m)
      if (island_quiet(label(m)) < self%time) cycle
      ! The island's id: its first body's global id, unique among islands asleep at once.
      self%island(i) = bodies%gid(root(label(m)))
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
      if (present(asleep_now)) then
        n = n + 1
        call push(asleep_now, n, i)
      end if
    end do
    if (present(n_asleep_now)) n_asleep_now = n
  end subroutine sleep_update

  !> Wakes the island of asleep body i; the bodies woken go to woken(n_woken+1:), n_woken grows.
  subroutine sleep_wake_island_of(self, bodies, flight, i, woken, n_woken)
    class(sleep_t), intent(inout) :: self
    type(bodies_t), intent(inout) :: bodies
    type(free_flight_t), intent(inout) :: flight
    integer, intent(in) :: i
    integer, allocatable, intent(inout) :: woken(:)
    integer, intent(inout) :: n_woken
    integer(i8) :: id
    integer :: k
    if (.not. bodies%asleep(i)) return
    id = self%island(i)
    ! (a scan of the owned bodies: waking is rare, the islands module's member lists are next)
    do k = 1, bodies%n_owned
      if (bodies%asleep(k) .and. self%island(k) == id) then
        call wake_body(self, bodies, flight, k)
        n_woken = n_woken + 1
        call push(woken, n_woken, k)
      end if
    end do
  end subroutine sleep_wake_island_of

  subroutine push(list, n, value)
    integer, allocatable, intent(inout) :: list(:)
    integer, intent(in) :: n, value
    integer, allocatable :: grown(:)
    if (.not. allocated(list)) allocate (list(16))
    if (n > size(list)) then
      allocate (grown(2*size(list)))
      grown(1:size(list)) = list
      call move_alloc(grown, list)
    end if
    list(n) = value
  end subroutine push

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
