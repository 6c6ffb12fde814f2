!> System totals used to tell the user how good a run was: energies, momentum, and angular
!> momentum about the system's centre of mass. Under uniform gravity with no contact with
!> fixed bodies, E = T + V, P - M g t and L_cm are exact invariants, so their drift is the
!> integration error.
module conservation
  use kinds, only: dp
  use vector_ops, only: cross
  use body_state, only: bodies_t
  use parallel_env, only: parallel_t
  implicit none
  private
  public :: system_totals_t, compute_totals

  type :: system_totals_t
    real(dp) :: kinetic_translational = 0.0_dp   !< [J]
    real(dp) :: kinetic_rotational = 0.0_dp      !< [J]
    real(dp) :: potential = 0.0_dp               !< [J] -sum m g.x, zero at the origin
    real(dp) :: mass = 0.0_dp                    !< [kg] of the moving bodies
    real(dp) :: momentum(3) = 0.0_dp             !< [kg m/s]
    real(dp) :: angular_momentum(3) = 0.0_dp     !< [kg m^2/s] about the centre of mass
    real(dp) :: centre_of_mass(3) = 0.0_dp       !< [m]
    !> sqrt(2 T sum(I_max)) [kg m^2/s]: the angular momentum the kinetic energy could carry,
    !> a scale for angular-momentum errors that does not vanish when L does.
    real(dp) :: angular_momentum_scale = 0.0_dp
  contains
    procedure :: energy => totals_energy
  end type system_totals_t

contains

  pure real(dp) function totals_energy(self)
    class(system_totals_t), intent(in) :: self
    totals_energy = self%kinetic_translational + self%kinetic_rotational + self%potential
  end function totals_energy

  !> Sums over the owned bodies of every rank (ghosts excluded, so nothing counts twice).
  subroutine compute_totals(par, bodies, gravity, totals)
    type(parallel_t), intent(in) :: par
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: gravity(3)
    type(system_totals_t), intent(out) :: totals
    real(dp) :: buffer(11), spin(3), et, er, x_rel(3), v_rel(3)
    integer :: i
    ! Two passes: totals, centre of mass and its velocity first, then angular momentum about
    ! the centre of mass from positions and velocities relative to it. (L_origin - X x P in
    ! one pass cancels two large terms: far from the origin its round-off would be
    ! reported as "conservation error".)
    buffer = 0.0_dp
    do i = 1, bodies%n_owned
      if (bodies%fixed(i) .and. .not. bodies%asleep(i)) cycle   ! asleep bodies still count
      call bodies%kinetic_energy(i, et, er)
      buffer(1) = buffer(1) + et
      buffer(2) = buffer(2) + er
      buffer(3) = buffer(3) - bodies%mass(i)*dot_product(gravity, bodies%x(:, i))
      buffer(4) = buffer(4) + bodies%mass(i)
      buffer(5:7) = buffer(5:7) + bodies%mass(i)*bodies%v(:, i)
      buffer(8:10) = buffer(8:10) + bodies%mass(i)*bodies%x(:, i)
      buffer(11) = buffer(11) + maxval(bodies%inertia(:, i))
    end do
    call par%sum_inplace(buffer)
    totals%kinetic_translational = buffer(1)
    totals%kinetic_rotational = buffer(2)
    totals%potential = buffer(3)
    totals%mass = buffer(4)
    totals%momentum = buffer(5:7)
    totals%angular_momentum_scale = sqrt(2.0_dp*(buffer(1) + buffer(2))*buffer(11))
    totals%centre_of_mass = 0.0_dp
    if (totals%mass > 0.0_dp) totals%centre_of_mass = buffer(8:10)/totals%mass
    spin = 0.0_dp
    do i = 1, bodies%n_owned
      if (bodies%fixed(i) .and. .not. bodies%asleep(i)) cycle   ! asleep bodies still count
      x_rel = bodies%x(:, i) - totals%centre_of_mass
      v_rel = bodies%v(:, i) - totals%momentum/max(totals%mass, tiny(1.0_dp))
      spin = spin + bodies%mass(i)*cross(x_rel, v_rel) + bodies%angular_momentum(i)
    end do
    call par%sum_inplace(spin)
    totals%angular_momentum = spin
  end subroutine compute_totals

end module conservation
