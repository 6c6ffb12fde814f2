!> Contact materials: each &body group has a coefficient of restitution e and a Coulomb
!> friction coefficient mu (its own, or the &contact value), and a contact between two
!> bodies uses a combination of the two groups' values (docs/input.md, &body and &contact):
!>  - e: the smaller of the two. The more dissipative body governs (a steel ball does not
!>    bounce off sand), a pair of one material keeps that material's e, the result stays in
!>    [0, 1], and it agrees with a group of simultaneous contacts, which already uses the
!>    smallest e of its pairs (impulse_solver).
!>  - mu: the geometric mean sqrt(mu_a mu_b), as Box2D: a pair of one material keeps its
!>    mu, and a frictionless body (ice, a lubricated face) makes every pair it is in
!>    frictionless, which an arithmetic mean would not.
!> Fixed bodies (floors, walls) have materials like any other body.
module contact_material
  use kinds, only: dp
  use input_config, only: deck_t
  implicit none
  private
  public :: combined_restitution, combined_friction, material_table_t

  !> Materials of the deck's &body groups, indexed by group number (bodies_t%group_id).
  type :: material_table_t
    real(dp), allocatable :: restitution(:)   !< e of group k, in [0, 1] [-]
    real(dp), allocatable :: friction(:)      !< mu of group k, >= 0 [-]
  contains
    procedure :: init
    procedure :: free
    procedure :: pair_restitution
    procedure :: pair_friction
  end type material_table_t

contains

  !> e of a contact between bodies of restitution e_a and e_b (each in [0, 1]) [-].
  pure real(dp) function combined_restitution(e_a, e_b)
    real(dp), intent(in) :: e_a, e_b
    combined_restitution = min(e_a, e_b)
  end function combined_restitution

  !> mu of a contact between bodies of friction mu_a and mu_b (each >= 0) [-]: their
  !> geometric mean. Equal values are returned exactly (a pair of one material keeps its
  !> mu bit for bit); otherwise sqrt(mu_a) sqrt(mu_b), which cannot overflow or underflow
  !> where the product mu_a mu_b of two extreme (but valid) deck values would.
  pure real(dp) function combined_friction(mu_a, mu_b)
    real(dp), intent(in) :: mu_a, mu_b
    if (mu_a == mu_b) then
      combined_friction = mu_a
    else if (mu_a == 0.0_dp .or. mu_b == 0.0_dp) then
      combined_friction = 0.0_dp
    else
      combined_friction = sqrt(mu_a)*sqrt(mu_b)
    end if
  end function combined_friction

  !> One entry per &body group of the validated deck: the group's own restitution and
  !> friction, or the &contact value where the group gives -1 (the default).
  subroutine init(self, deck)
    class(material_table_t), intent(inout) :: self
    type(deck_t), intent(in) :: deck
    integer :: k, n
    call self%free()
    n = 0
    if (allocated(deck%bodies)) n = deck%n_bodies
    allocate (self%restitution(n), self%friction(n))
    do k = 1, n
      ! The reader allows only -1 or a valid value, so any negative value means "unset".
      if (deck%bodies(k)%restitution >= 0.0_dp) then
        self%restitution(k) = deck%bodies(k)%restitution
      else
        self%restitution(k) = deck%contact%restitution
      end if
      if (deck%bodies(k)%friction >= 0.0_dp) then
        self%friction(k) = deck%bodies(k)%friction
      else
        self%friction(k) = deck%contact%friction
      end if
    end do
  end subroutine init

  subroutine free(self)
    class(material_table_t), intent(inout) :: self
    if (allocated(self%restitution)) deallocate (self%restitution)
    if (allocated(self%friction)) deallocate (self%friction)
  end subroutine free

  !> e of a contact between a body of group group_a and one of group group_b [-].
  pure real(dp) function pair_restitution(self, group_a, group_b)
    class(material_table_t), intent(in) :: self
    integer, intent(in) :: group_a, group_b
    pair_restitution = combined_restitution(self%restitution(group_a), self%restitution(group_b))
  end function pair_restitution

  !> mu of a contact between a body of group group_a and one of group group_b [-].
  pure real(dp) function pair_friction(self, group_a, group_b)
    class(material_table_t), intent(in) :: self
    integer, intent(in) :: group_a, group_b
    pair_friction = combined_friction(self%friction(group_a), self%friction(group_b))
  end function pair_friction

end module contact_material
