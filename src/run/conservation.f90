!> System totals used to tell the user how good a run was: energies, momentum, and angular
!> momentum about the system's centre of mass. Under uniform gravity with no contact with
!> fixed bodies, E = T + V, P - M g t and L_cm are exact invariants, so their drift is the
!> integration error.
module conservation
  use kinds, only: dp
  use vector_ops, only: cross
  use body_state, only: bodies_t
  use parallel_env, only: parallel_t
  use exact_sum, only: exact_sum_t
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
  !> Every total is an exact sum (exact_sum) of the bodies' terms, each term computed from
  !> its body alone, reduced over the ranks as integers and rounded once: the totals are
  !> bitwise the same for any number of ranks and any order of the bodies (issue 18).
  subroutine compute_totals(par, bodies, gravity, totals)
    type(parallel_t), intent(in) :: par
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: gravity(3)
    type(system_totals_t), intent(out) :: totals
    ! first pass: 1 T_trans, 2 T_rot, 3 V, 4 M, 5:7 P, 8:10 sum m x, 11 sum I_max
    type(exact_sum_t) :: first(11), spin(3)
    real(dp) :: buffer(11), et, er, x_rel(3), v_rel(3), v_mean(3)
    integer :: i
    ! Two passes: totals, centre of mass and its velocity first, then angular momentum about
    ! the centre of mass from positions and velocities relative to it. (L_origin - X x P in
    ! one pass cancels two large terms: far from the origin its round-off would be
    ! reported as "conservation error".) The second pass's centre of mass and mean
    ! velocity come from the rounded exact first-pass totals, so they too are the same on
    ! every rank and for every split.
    do i = 1, bodies%n_owned
      if (bodies%fixed(i) .and. .not. bodies%asleep(i)) cycle   ! asleep bodies still count
      call bodies%kinetic_energy(i, et, er)
      call first(1)%add(et)
      call first(2)%add(er)
      call first(3)%add(-bodies%mass(i)*dot_product(gravity, bodies%x(:, i)))
      call first(4)%add(bodies%mass(i))
      call first(5:7)%add(bodies%mass(i)*bodies%v(:, i))
      call first(8:10)%add(bodies%mass(i)*bodies%x(:, i))
      call first(11)%add(maxval(bodies%inertia(:, i)))
    end do
    call par%sum_inplace(first)
    buffer = first%value()
    totals%kinetic_translational = buffer(1)
    totals%kinetic_rotational = buffer(2)
    totals%potential = buffer(3)
    totals%mass = buffer(4)
    totals%momentum = buffer(5:7)
    totals%angular_momentum_scale = sqrt(2.0_dp*(buffer(1) + buffer(2))*buffer(11))
    totals%centre_of_mass = 0.0_dp
    if (totals%mass > 0.0_dp) totals%centre_of_mass = buffer(8:10)/totals%mass
    v_mean = totals%momentum/max(totals%mass, tiny(1.0_dp))
    do i = 1, bodies%n_owned
      if (bodies%fixed(i) .and. .not. bodies%asleep(i)) cycle   ! asleep bodies still count
      x_rel = bodies%x(:, i) - totals%centre_of_mass
      v_rel = bodies%v(:, i) - v_mean
      call spin%add(bodies%mass(i)*cross(x_rel, v_rel))
      call spin%add(bodies%angular_momentum(i))
    end do
    call par%sum_inplace(spin)
    totals%angular_momentum = spin%value()
  end subroutine compute_totals

end module conservation
