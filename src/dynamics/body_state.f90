!> State of all bodies a rank holds, as a structure of arrays: owned bodies in 1:n_owned,
!> ghost copies from neighbouring ranks after them (none on one rank). Bodies carry global
!> ids so that output, restart and runs on any number of ranks agree.
!>
!> Internally a body lives in its shape's principal frame: q rotates principal-frame vectors
!> into the world and x is the centre of mass. Users see the shape's own frame instead
!> (user_orientation), as decks, outputs and checkpoints do.
module body_state
  use kinds, only: dp, i8
  use quaternion, only: quat_rotate, quat_rotate_inverse
  use error_status, only: error_t, ERR_INTERNAL
  use sorting, only: sort_index_keys
  use string_utils, only: str
  use row_journal, only: row_journal_t
  implicit none
  private
  public :: bodies_t, copy_row

  !> words of a row in the undo journal: x(3), q(4), v(3), w(3), a(3), alpha(3), asleep
  integer, parameter :: journal_width = 20

  type :: bodies_t
    integer :: n_owned = 0
    integer :: n_ghost = 0
    integer(i8), allocatable :: gid(:)          !< global id, 1-based, unique over the run
    integer, allocatable :: shape_id(:)         !< index into the shape library
    integer, allocatable :: group_id(:)         !< which &body group of the deck made it
    logical, allocatable :: fixed(:)            !< static: infinite mass, never moves
    !> asleep (contact/sleeping.f90): held still like a static body (fixed set, inverse mass
    !> and inertia 0) until something touches it; counts as a moving body in the totals
    logical, allocatable :: asleep(:)
    real(dp), allocatable :: mass(:)            !< [kg] (huge for fixed bodies; use inv_mass)
    real(dp), allocatable :: inv_mass(:)        !< [1/kg], 0 for fixed bodies
    real(dp), allocatable :: inertia(:, :)      !< (3,n) principal moments [kg m^2]
    real(dp), allocatable :: inv_inertia(:, :)  !< (3,n) their inverses, 0 for fixed bodies
    real(dp), allocatable :: x(:, :)            !< (3,n) centre of mass, world [m]
    real(dp), allocatable :: q(:, :)            !< (4,n) principal frame -> world
    real(dp), allocatable :: v(:, :)            !< (3,n) velocity of the centre of mass [m/s]
    real(dp), allocatable :: w(:, :)            !< (3,n) angular velocity, world frame [rad/s]
    real(dp), allocatable :: a(:, :)            !< (3,n) linear acceleration (Newmark state) [m/s^2]
    real(dp), allocatable :: alpha(:, :)        !< (3,n) angular acceleration, world (Newmark state) [rad/s^2]
    !> An undo journal of the motion state (a cross-rank window's save, docs/architecture.md
    !> "Cross-rank contacts: windows with ghosts", step 4): while it runs, touch(i) before a
    !> change of row i keeps the row's x, q, v, w, a, alpha and asleep as they were, the first
    !> time; roll_back puts them back (the rows held are those of the start: a window adds
    !> none). The event loop touches every row it evaluates or changes (sync, count_change).
    type(row_journal_t) :: journal
    integer :: journal_rows(2) = 0              !< n_owned, n_ghost at the journal's start
  contains
    procedure :: allocate => bodies_allocate
    procedure :: free => bodies_free
    procedure :: n_total => bodies_n_total
    procedure :: angular_momentum => bodies_angular_momentum
    procedure :: kinetic_energy => bodies_kinetic_energy
    procedure :: world_inertia_apply => bodies_world_inertia_apply
    procedure :: capacity => bodies_capacity
    procedure :: reserve => bodies_reserve
    procedure :: open_rows => bodies_open_rows
    procedure :: append_rows => bodies_append_rows
    procedure :: append_row => bodies_append_row
    generic :: remove_rows => remove_rows_mask, remove_rows_list
    procedure, private :: remove_rows_mask => bodies_remove_rows_mask
    procedure, private :: remove_rows_list => bodies_remove_rows_list
    procedure :: sort_owned_by_gid => bodies_sort_owned_by_gid
    procedure :: touch => bodies_touch
    procedure :: start_journal => bodies_start_journal
    procedure :: roll_back => bodies_roll_back
    procedure :: stop_journal => bodies_stop_journal
  end type bodies_t

contains

  subroutine bodies_allocate(self, capacity)
    class(bodies_t), intent(inout) :: self
    integer, intent(in) :: capacity
    call self%free()
    allocate (self%gid(capacity), self%shape_id(capacity), self%group_id(capacity), self%fixed(capacity), &
              self%asleep(capacity))
    allocate (self%mass(capacity), self%inv_mass(capacity))
    allocate (self%inertia(3, capacity), self%inv_inertia(3, capacity))
    allocate (self%x(3, capacity), self%q(4, capacity), self%v(3, capacity), self%w(3, capacity))
    allocate (self%a(3, capacity), self%alpha(3, capacity))
    self%gid = 0; self%shape_id = 0; self%group_id = 0; self%fixed = .false.; self%asleep = .false.
    self%mass = 0; self%inv_mass = 0; self%inertia = 0; self%inv_inertia = 0
    self%x = 0; self%v = 0; self%w = 0; self%a = 0; self%alpha = 0
    self%q = 0; self%q(1, :) = 1
  end subroutine bodies_allocate

  subroutine bodies_free(self)
    class(bodies_t), intent(inout) :: self
    if (allocated(self%gid)) deallocate (self%gid, self%shape_id, self%group_id, self%fixed, self%asleep, self%mass, &
                                         self%inv_mass, self%inertia, self%inv_inertia, self%x, self%q, &
                                         self%v, self%w, self%a, self%alpha)
    self%n_owned = 0
    self%n_ghost = 0
  end subroutine bodies_free

  pure integer function bodies_n_total(self)
    class(bodies_t), intent(in) :: self
    bodies_n_total = self%n_owned + self%n_ghost
  end function bodies_n_total

  !> J_world w = R J R^T w for body i (J principal, R = R(q)).
  pure function bodies_world_inertia_apply(self, i, vector) result(jv)
    class(bodies_t), intent(in) :: self
    integer, intent(in) :: i
    real(dp), intent(in) :: vector(3)
    real(dp) :: jv(3)
    jv = quat_rotate(self%q(:, i), self%inertia(:, i)*quat_rotate_inverse(self%q(:, i), vector))
  end function bodies_world_inertia_apply

  !> Angular momentum of body i about its centre of mass, world frame [kg m^2/s].
  pure function bodies_angular_momentum(self, i) result(l)
    class(bodies_t), intent(in) :: self
    integer, intent(in) :: i
    real(dp) :: l(3)
    l = self%world_inertia_apply(i, self%w(:, i))
  end function bodies_angular_momentum

  !> Translational and rotational kinetic energy of body i [J] (0 for fixed bodies).
  pure subroutine bodies_kinetic_energy(self, i, translational, rotational)
    class(bodies_t), intent(in) :: self
    integer, intent(in) :: i
    real(dp), intent(out) :: translational, rotational
    real(dp) :: wb(3)
    if (self%fixed(i)) then
      translational = 0.0_dp
      rotational = 0.0_dp
      return
    end if
    translational = 0.5_dp*self%mass(i)*dot_product(self%v(:, i), self%v(:, i))
    wb = quat_rotate_inverse(self%q(:, i), self%w(:, i))
    rotational = 0.5_dp*dot_product(wb, self%inertia(:, i)*wb)
  end subroutine bodies_kinetic_energy

  ! ---- Row operations: what migration and the halo exchange do to a rank's bodies. Rows
  ! keep the owned-then-ghost order (owned in 1:n_owned, ghosts after them); callers that
  ! hold per-body arrays of their own (anchors, versions, grid placements) remap them with
  ! the new_index these return.

  !> Row i of from becomes row j of to (both rows must exist; counts are not changed).
  subroutine copy_row(from, i, to, j)
    type(bodies_t), intent(in) :: from
    integer, intent(in) :: i, j
    type(bodies_t), intent(inout) :: to
    to%gid(j) = from%gid(i)
    to%shape_id(j) = from%shape_id(i)
    to%group_id(j) = from%group_id(i)
    to%fixed(j) = from%fixed(i)
    to%asleep(j) = from%asleep(i)
    to%mass(j) = from%mass(i)
    to%inv_mass(j) = from%inv_mass(i)
    to%inertia(:, j) = from%inertia(:, i)
    to%inv_inertia(:, j) = from%inv_inertia(:, i)
    to%x(:, j) = from%x(:, i)
    to%q(:, j) = from%q(:, i)
    to%v(:, j) = from%v(:, i)
    to%w(:, j) = from%w(:, i)
    to%a(:, j) = from%a(:, i)
    to%alpha(:, j) = from%alpha(:, i)
  end subroutine copy_row

  !> Rows the arrays have room for (0 before allocate).
  pure integer function bodies_capacity(self)
    class(bodies_t), intent(in) :: self
    bodies_capacity = 0
    if (allocated(self%gid)) bodies_capacity = size(self%gid)
  end function bodies_capacity

  !> Room for at least `capacity` rows, keeping the rows held.
  subroutine bodies_reserve(self, capacity)
    class(bodies_t), intent(inout) :: self
    integer, intent(in) :: capacity
    type(bodies_t) :: grown
    integer :: k
    if (self%capacity() >= capacity) return
    call grown%allocate(capacity)
    do k = 1, self%n_total()
      call copy_row(self, k, grown, k)
    end do
    grown%n_owned = self%n_owned
    grown%n_ghost = self%n_ghost
    call take_storage(self, grown)
  end subroutine bodies_reserve

  !> m new rows, reset (at rest at the origin, ids 0), for the caller to fill: owned rows
  !> at n_owned+1.. (the ghosts move up by m, in order: one shift per call, so append in
  !> bulk), ghost rows at the end. first: the first new row. Capacity grows geometrically.
  subroutine bodies_open_rows(self, m, as_ghost, first)
    class(bodies_t), intent(inout) :: self
    integer, intent(in) :: m
    logical, intent(in) :: as_ghost
    integer, intent(out) :: first
    integer :: n, k
    n = self%n_total()
    if (n + m > self%capacity()) call self%reserve(max(n + m, 2*self%capacity(), 16))
    if (as_ghost) then
      first = n + 1
      self%n_ghost = self%n_ghost + m
    else
      first = self%n_owned + 1
      if (self%n_ghost > 0 .and. m > 0) call place_rows(self, [(k, k=self%n_owned + 1, n)], self%n_owned + m + 1)
      self%n_owned = self%n_owned + m
    end if
    do k = first, first + m - 1
      call reset_row(self, k)
    end do
  end subroutine bodies_open_rows

  !> Rows rows(:) of from appended as owned or ghost rows, in that order.
  subroutine bodies_append_rows(self, from, rows, as_ghost)
    class(bodies_t), intent(inout) :: self
    type(bodies_t), intent(in) :: from
    integer, intent(in) :: rows(:)
    logical, intent(in) :: as_ghost
    integer :: first, k
    call self%open_rows(size(rows), as_ghost, first)
    do k = 1, size(rows)
      call copy_row(from, rows(k), self, first + k - 1)
    end do
  end subroutine bodies_append_rows

  subroutine bodies_append_row(self, from, i, as_ghost)
    class(bodies_t), intent(inout) :: self
    type(bodies_t), intent(in) :: from
    integer, intent(in) :: i
    logical, intent(in) :: as_ghost
    call self%append_rows(from, [i], as_ghost)
  end subroutine bodies_append_row

  !> Drops the rows k with remove(k) (size n_total), keeping the order of the others, owned
  !> still first. new_index(k): the row old row k moved to, 0 if removed.
  subroutine bodies_remove_rows_mask(self, remove, err, new_index)
    class(bodies_t), intent(inout) :: self
    logical, intent(in) :: remove(:)
    type(error_t), intent(inout) :: err
    integer, intent(out), optional :: new_index(:)
    integer, allocatable :: keep(:)
    integer :: n, k, kept_owned
    n = self%n_total()
    if (size(remove) /= n) then
      call err%set(ERR_INTERNAL, 'bodies: remove_rows got a mask of '//str(size(remove))//' rows for '// &
                   str(n)//' bodies')
      return
    end if
    if (present(new_index)) then
      if (size(new_index) < n) then
        call err%set(ERR_INTERNAL, 'bodies: remove_rows: new_index is shorter than the '//str(n)//' rows')
        return
      end if
    end if
    keep = pack([(k, k=1, n)], .not. remove)
    kept_owned = count(.not. remove(1:self%n_owned))
    if (present(new_index)) then
      new_index(1:n) = 0
      do k = 1, size(keep)
        new_index(keep(k)) = k
      end do
    end if
    if (size(keep) < n) call place_rows(self, keep, 1)
    self%n_ghost = size(keep) - kept_owned
    self%n_owned = kept_owned
  end subroutine bodies_remove_rows_mask

  !> Drops the listed rows (1..n_total; repeats allowed), as remove_rows with a mask.
  subroutine bodies_remove_rows_list(self, rows, err, new_index)
    class(bodies_t), intent(inout) :: self
    integer, intent(in) :: rows(:)
    type(error_t), intent(inout) :: err
    integer, intent(out), optional :: new_index(:)
    logical, allocatable :: remove(:)
    integer :: k
    allocate (remove(self%n_total()))
    remove = .false.
    do k = 1, size(rows)
      if (rows(k) < 1 .or. rows(k) > self%n_total()) then
        call err%set(ERR_INTERNAL, 'bodies: remove_rows: row '//str(rows(k))//' is not in 1..'// &
                     str(self%n_total()))
        return
      end if
      remove(rows(k)) = .true.
    end do
    call self%remove_rows_mask(remove, err, new_index)
  end subroutine bodies_remove_rows_list

  !> Owned rows in increasing global id (stable; ghosts untouched): the order output and
  !> checkpoints use. new_index as for remove_rows (ghosts map to themselves).
  subroutine bodies_sort_owned_by_gid(self, new_index)
    class(bodies_t), intent(inout) :: self
    integer, intent(out), optional :: new_index(:)
    integer, allocatable :: order(:)
    integer :: k, n
    n = self%n_owned
    call sort_index_keys(reshape(self%gid(1:n), [1, n]), order)
    if (present(new_index)) then
      do k = 1, n
        new_index(order(k)) = k
      end do
      do k = n + 1, self%n_total()
        new_index(k) = k
      end do
    end if
    if (n > 1) call place_rows(self, order, 1)
  end subroutine bodies_sort_owned_by_gid

  !> Rows first.. become the old rows src(:) (array assignment: overlaps are safe).
  subroutine place_rows(b, src, first)
    type(bodies_t), intent(inout) :: b
    integer, intent(in) :: src(:)
    integer, intent(in) :: first
    integer :: last
    last = first + size(src) - 1
    b%gid(first:last) = b%gid(src)
    b%shape_id(first:last) = b%shape_id(src)
    b%group_id(first:last) = b%group_id(src)
    b%fixed(first:last) = b%fixed(src)
    b%asleep(first:last) = b%asleep(src)
    b%mass(first:last) = b%mass(src)
    b%inv_mass(first:last) = b%inv_mass(src)
    b%inertia(:, first:last) = b%inertia(:, src)
    b%inv_inertia(:, first:last) = b%inv_inertia(:, src)
    b%x(:, first:last) = b%x(:, src)
    b%q(:, first:last) = b%q(:, src)
    b%v(:, first:last) = b%v(:, src)
    b%w(:, first:last) = b%w(:, src)
    b%a(:, first:last) = b%a(:, src)
    b%alpha(:, first:last) = b%alpha(:, src)
  end subroutine place_rows

  !> Row k as allocate leaves it.
  subroutine reset_row(b, k)
    type(bodies_t), intent(inout) :: b
    integer, intent(in) :: k
    b%gid(k) = 0; b%shape_id(k) = 0; b%group_id(k) = 0; b%fixed(k) = .false.; b%asleep(k) = .false.
    b%mass(k) = 0; b%inv_mass(k) = 0; b%inertia(:, k) = 0; b%inv_inertia(:, k) = 0
    b%x(:, k) = 0; b%v(:, k) = 0; b%w(:, k) = 0; b%a(:, k) = 0; b%alpha(:, k) = 0
    b%q(:, k) = [1, 0, 0, 0]
  end subroutine reset_row

  !> to takes from's arrays and counts (from is left empty).
  subroutine take_storage(to, from)
    type(bodies_t), intent(inout) :: to, from
    call to%free()
    call move_alloc(from%gid, to%gid); call move_alloc(from%shape_id, to%shape_id)
    call move_alloc(from%group_id, to%group_id); call move_alloc(from%fixed, to%fixed)
    call move_alloc(from%asleep, to%asleep); call move_alloc(from%mass, to%mass)
    call move_alloc(from%inv_mass, to%inv_mass); call move_alloc(from%inertia, to%inertia)
    call move_alloc(from%inv_inertia, to%inv_inertia); call move_alloc(from%x, to%x)
    call move_alloc(from%q, to%q); call move_alloc(from%v, to%v); call move_alloc(from%w, to%w)
    call move_alloc(from%a, to%a); call move_alloc(from%alpha, to%alpha)
    to%n_owned = from%n_owned
    to%n_ghost = from%n_ghost
    from%n_owned = 0
    from%n_ghost = 0
  end subroutine take_storage

  !> While journaling: row i's motion state is about to change; the first time since the
  !> journal's start (or roll_back), it is kept as it is now.
  subroutine bodies_touch(self, i)
    class(bodies_t), intent(inout) :: self
    integer, intent(in) :: i
    integer :: m
    integer(i8), parameter :: mold = 0_i8
    if (.not. self%journal%active) return
    m = self%journal%keep(i)
    if (m == 0) return
    associate (words => self%journal%words(:, m))
      words(1:3) = transfer(self%x(:, i), mold, 3)
      words(4:7) = transfer(self%q(:, i), mold, 4)
      words(8:10) = transfer(self%v(:, i), mold, 3)
      words(11:13) = transfer(self%w(:, i), mold, 3)
      words(14:16) = transfer(self%a(:, i), mold, 3)
      words(17:19) = transfer(self%alpha(:, i), mold, 3)
      words(20) = merge(1_i8, 0_i8, self%asleep(i))
    end associate
  end subroutine bodies_touch

  !> From now on the first change of each row's motion state is kept (touch), until
  !> roll_back or stop_journal: the state roll_back returns to.
  subroutine bodies_start_journal(self)
    class(bodies_t), intent(inout) :: self
    call self%journal%start(self%n_owned + self%n_ghost, journal_width)
    self%journal_rows = [self%n_owned, self%n_ghost]
  end subroutine bodies_start_journal

  !> No more journal (what it kept is dropped).
  subroutine bodies_stop_journal(self)
    class(bodies_t), intent(inout) :: self
    call self%journal%stop()
  end subroutine bodies_stop_journal

  !> Every row touched since start_journal back as it was then, bit for bit; the journal
  !> goes on from there. O(rows touched). err: the rows held changed meanwhile (rows added
  !> or removed under a journal: an internal error, nothing rolled back).
  subroutine bodies_roll_back(self, err)
    class(bodies_t), intent(inout) :: self
    type(error_t), intent(inout) :: err
    integer :: m, i
    if (.not. self%journal%active .or. any([self%n_owned, self%n_ghost] /= self%journal_rows)) then
      call err%set(ERR_INTERNAL, 'bodies: a roll back without its journal (rows held '//str(self%n_owned)//' + '// &
                   str(self%n_ghost)//', at the start '//str(self%journal_rows(1))//' + '//str(self%journal_rows(2))//')')
      return
    end if
    do m = 1, self%journal%n
      i = self%journal%ids(m)
      associate (words => self%journal%words(:, m))
        self%x(:, i) = transfer(words(1:3), 1.0_dp, 3)
        self%q(:, i) = transfer(words(4:7), 1.0_dp, 4)
        self%v(:, i) = transfer(words(8:10), 1.0_dp, 3)
        self%w(:, i) = transfer(words(11:13), 1.0_dp, 3)
        self%a(:, i) = transfer(words(14:16), 1.0_dp, 3)
        self%alpha(:, i) = transfer(words(17:19), 1.0_dp, 3)
        self%asleep(i) = words(20) /= 0
      end associate
    end do
    call self%journal%clear()
  end subroutine bodies_roll_back

end module body_state
