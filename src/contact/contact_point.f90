!> One contact point between two bodies, as every contact solver takes it.
module contact_point
  use kinds, only: dp
  implicit none
  private
  public :: contact_t

  !> One contact point between bodies a and b (indices into bodies_t, both valid; either
  !> may be fixed).
  type :: contact_t
    integer :: a = 0
    integer :: b = 0
    real(dp) :: point(3) = 0.0_dp     !< world contact point [m]
    real(dp) :: normal(3) = 0.0_dp    !< unit normal from a to b
    real(dp) :: restitution = 0.0_dp  !< e of this pair (0 below the rest speed; the group uses
                                      !< the smallest over its approaching contacts)
    real(dp) :: friction = 0.0_dp     !< Coulomb mu of this pair
    !> Contact pass, inelastic pairs: this contact may keep approaching at up to this speed,
    !> the speed that closes its own feature gap to target + tolerance in exactly the step
    !> (speculative contacts, not yet in the band; also contacts in the band above that
    !> height), 0 at or below it, less the closing that the bodies' turning adds by the
    !> step's end (negative: the contact must open at that speed); 0 for elastic pairs [m/s].
    real(dp) :: allowed_approach = 0.0_dp
    !> Contact pass: the features are above target + tolerance (not touching yet)
    logical :: speculative = .false.
    !> Contact pass, inelastic pairs: allowed_approach without the turning term [m/s]; the
    !> solver takes the turning term again from the velocities it found (turning = .true.)
    real(dp) :: allowed_straight = 0.0_dp
    logical :: turning = .false.
    real(dp) :: gap = 0.0_dp          !< distance of the two features when found [m]
  end type contact_t

end module contact_point
