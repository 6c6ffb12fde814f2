!> Contact forces kept between contact passes to warm-start the next one, keyed by a
!> contact's key (the two bodies' global ids and the features' ids), for the local event
!> loop: there every island solves its own pass at its own time, so the forces of one
!> island must survive the passes of the others (the global loop's pass covers every
!> contact at once and keeps only its own). An open-addressing hash table; an entry is
!> used only if it is recent (written at or after the time asked for: the island's
!> previous step), and old entries are dropped when the table fills.
module warm_start_cache
  use kinds, only: dp, i8
  implicit none
  private
  public :: warm_cache_t

  integer, parameter :: KEY_WORDS = 7

  type :: warm_cache_t
    integer :: size = 0                       !< slots (a power of two)
    integer :: used = 0                       !< slots holding an entry
    integer(i8), allocatable :: keys(:, :)    !< (KEY_WORDS, slot)
    real(dp), allocatable :: force(:, :)      !< (3, slot) [N]
    real(dp), allocatable :: written(:)       !< time the entry was written [s]
    logical, allocatable :: full(:)
  contains
    procedure :: init => cache_init
    procedure :: lookup => cache_lookup
    procedure :: store => cache_store
    procedure :: clear => cache_clear
  end type warm_cache_t

contains

  subroutine cache_init(self, capacity)
    class(warm_cache_t), intent(inout) :: self
    integer, intent(in) :: capacity
    integer :: s
    s = 1024
    do while (s < 2*capacity)
      s = 2*s
    end do
    if (allocated(self%keys)) deallocate (self%keys, self%force, self%written, self%full)
    allocate (self%keys(KEY_WORDS, s), self%force(3, s), self%written(s), self%full(s))
    self%full = .false.
    self%size = s
    self%used = 0
  end subroutine cache_init

  subroutine cache_clear(self)
    class(warm_cache_t), intent(inout) :: self
    if (allocated(self%full)) self%full = .false.
    self%used = 0
  end subroutine cache_clear

  pure integer function slot_of(key, size) result(s)
    integer(i8), intent(in) :: key(:)
    integer, intent(in) :: size
    integer(i8) :: h
    integer :: k
    h = 1469598103934665603_i8
    do k = 1, size_of_key(key)
      h = ieor(h, key(k))
      h = h*1099511628211_i8
    end do
    h = ieor(h, ishft(h, -29))
    s = int(iand(h, int(size - 1, i8))) + 1
  end function slot_of

  pure integer function size_of_key(key)
    integer(i8), intent(in) :: key(:)
    size_of_key = min(size(key), KEY_WORDS)
  end function size_of_key

  !> The force stored for key if written at or after `since` [s]; found tells.
  subroutine cache_lookup(self, key, since, force, found)
    class(warm_cache_t), intent(in) :: self
    integer(i8), intent(in) :: key(:)
    real(dp), intent(in) :: since
    real(dp), intent(out) :: force(3)
    logical, intent(out) :: found
    integer :: s, probes
    found = .false.
    force = 0.0_dp
    if (self%size == 0) return
    s = slot_of(key, self%size)
    do probes = 1, self%size
      if (.not. self%full(s)) return
      if (all(self%keys(:, s) == key)) then
        if (self%written(s) >= since) then
          force = self%force(:, s)
          found = .true.
        end if
        return
      end if
      s = s + 1
      if (s > self%size) s = 1
    end do
  end subroutine cache_lookup

  !> Stores force for key at time t; entries older than `keep_since` may be dropped to
  !> make room.
  subroutine cache_store(self, key, force, t, keep_since)
    class(warm_cache_t), intent(inout) :: self
    integer(i8), intent(in) :: key(:)
    real(dp), intent(in) :: force(3), t, keep_since
    integer :: s
    if (self%size == 0) call self%init(1024)
    if (2*(self%used + 1) > self%size) call rebuild(self, keep_since)
    s = slot_of(key, self%size)
    do
      if (.not. self%full(s)) exit
      if (all(self%keys(:, s) == key)) then
        self%force(:, s) = force
        self%written(s) = t
        return
      end if
      s = s + 1
      if (s > self%size) s = 1
    end do
    self%full(s) = .true.
    self%keys(:, s) = key
    self%force(:, s) = force
    self%written(s) = t
    self%used = self%used + 1
  end subroutine cache_store

  !> The recent entries into a table twice their number (at least the present size).
  subroutine rebuild(self, keep_since)
    type(warm_cache_t), intent(inout) :: self
    real(dp), intent(in) :: keep_since
    integer(i8), allocatable :: keys(:, :)
    real(dp), allocatable :: force(:, :), written(:)
    logical, allocatable :: full(:)
    integer :: s, kept, new_size, t
    kept = count(self%full .and. self%written >= keep_since)
    new_size = self%size
    do while (new_size < 4*(kept + 1))
      new_size = 2*new_size
    end do
    call move_alloc(self%keys, keys)
    call move_alloc(self%force, force)
    call move_alloc(self%written, written)
    call move_alloc(self%full, full)
    allocate (self%keys(KEY_WORDS, new_size), self%force(3, new_size), self%written(new_size), self%full(new_size))
    self%full = .false.
    self%size = new_size
    self%used = 0
    do s = 1, size(full)
      if (.not. full(s)) cycle
      if (written(s) < keep_since) cycle
      t = slot_of(keys(:, s), new_size)
      do while (self%full(t))
        t = t + 1
        if (t > new_size) t = 1
      end do
      self%full(t) = .true.
      self%keys(:, t) = keys(:, s)
      self%force(:, t) = force(:, s)
      self%written(t) = written(s)
      self%used = self%used + 1
    end do
  end subroutine rebuild

end module warm_start_cache
