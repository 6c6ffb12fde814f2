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
  implicit none
  private
  public :: bodies_t

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
  contains
    procedure :: allocate => bodies_allocate
    procedure :: free => bodies_free
    procedure :: n_total => bodies_n_total
    procedure :: angular_momentum => bodies_angular_momentum
    procedure :: kinetic_energy => bodies_kinetic_energy
    procedure :: world_inertia_apply => bodies_world_inertia_apply
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

end module body_state
