!> Contact materials: each &body group has a coefficient of restitution e and a Coulomb
!> friction coefficient mu (its own, or the &contact value), and a contact between two
!> bodies combines the two groups' values by &contact's rules (docs/input.md, docs/contact.md):
!>  - restitution_rule: 'min' (default), 'max' or 'mean'. 'min': the more dissipative body
!>    governs (a steel ball does not bounce off sand). Every rule keeps a pair of one material
!>    at that material's e exactly and the result in [0, 1]; a deck whose bodies share one e
!>    (every validation deck) runs identically under each.
!>  - friction_rule: 'geometric' (default, sqrt(mu_a mu_b), as Box2D), 'min', 'max' or
!>    'mean'. The geometric mean keeps a pair of one material at its mu, and a frictionless
!>    body (ice, a lubricated face) makes every pair it is in frictionless, which an
!>    arithmetic mean would not.
!> Each contact of a simultaneous impact then uses its own pair's e (impulse_solver).
!> Fixed bodies (floors, walls) have materials like any other body.
module contact_material
  use kinds, only: dp
  use input_config, only: contact_config_t, RULE_MIN, RULE_MAX, RULE_MEAN, RULE_GEOMETRIC
  implicit none
  private
  public :: combined_restitution, combined_friction, material_table_t

  !> The rules as codes, so that a pair's value (asked for at every candidate pair) costs no
  !> string comparison.
  integer, parameter :: CODE_MIN = 1, CODE_MAX = 2, CODE_MEAN = 3, CODE_GEOMETRIC = 4

  !> Materials of the deck's &body groups, indexed by group number (bodies_t%group_id).
  type :: material_table_t
    real(dp), allocatable :: restitution(:)   !< e of group k, in [0, 1] [-]
    real(dp), allocatable :: friction(:)      !< mu of group k, >= 0 [-]
    integer :: restitution_rule = CODE_MIN    !< a CODE_ of &contact's restitution_rule
    integer :: friction_rule = CODE_GEOMETRIC !< a CODE_ of &contact's friction_rule
  contains
    procedure :: init
    procedure :: free
    procedure :: pair_restitution
    procedure :: pair_friction
  end type material_table_t

contains

  !> e of a contact between bodies of restitution e_a and e_b (each in [0, 1]) [-], by
  !> rule (RULE_MIN, RULE_MAX or RULE_MEAN; absent: RULE_MIN). Equal values are returned
  !> exactly by every rule.
  pure real(dp) function combined_restitution(e_a, e_b, rule)
    real(dp), intent(in) :: e_a, e_b
    character(len=*), intent(in), optional :: rule
    combined_restitution = combine(e_a, e_b, RULE_MIN, rule)
  end function combined_restitution

  !> mu of a contact between bodies of friction mu_a and mu_b (each >= 0) [-], by rule
  !> (RULE_GEOMETRIC, RULE_MIN, RULE_MAX or RULE_MEAN; absent: RULE_GEOMETRIC).
  pure real(dp) function combined_friction(mu_a, mu_b, rule)
    real(dp), intent(in) :: mu_a, mu_b
    character(len=*), intent(in), optional :: rule
    combined_friction = combine(mu_a, mu_b, RULE_GEOMETRIC, rule)
  end function combined_friction

  !> The code of a rule's name (CODE_MIN where the name is none of them: the reader admits
  !> only known names).
  pure integer function rule_code(rule)
    character(len=*), intent(in) :: rule
    select case (trim(rule))
    case (RULE_MAX)
      rule_code = CODE_MAX
    case (RULE_MEAN)
      rule_code = CODE_MEAN
    case (RULE_GEOMETRIC)
      rule_code = CODE_GEOMETRIC
    case default
      rule_code = CODE_MIN
    end select
  end function rule_code

  !> a and b (>= 0) combined by rule (the name), or by default_rule where it is absent.
  pure real(dp) function combine(a, b, default_rule, rule)
    real(dp), intent(in) :: a, b
    character(len=*), intent(in) :: default_rule
    character(len=*), intent(in), optional :: rule
    if (present(rule)) then
      combine = combine_code(a, b, rule_code(rule))
    else
      combine = combine_code(a, b, rule_code(default_rule))
    end if
  end function combine

  !> a and b (>= 0) combined by the rule of code `code`. Equal values are returned exactly
  !> (a pair of one material keeps its value bit for bit, whatever the rule). The geometric
  !> mean is sqrt(a) sqrt(b), which cannot overflow or underflow where the product a b of two
  !> extreme (but valid) deck values would, and is 0 when either is; the arithmetic mean is
  !> a/2 + b/2 for the same reason.
  pure real(dp) function combine_code(a, b, code)
    real(dp), intent(in) :: a, b
    integer, intent(in) :: code
    if (a == b) then
      combine_code = a
      return
    end if
    select case (code)
    case (CODE_MAX)
      combine_code = max(a, b)
    case (CODE_MEAN)
      combine_code = 0.5_dp*a + 0.5_dp*b
    case (CODE_GEOMETRIC)
      if (a == 0.0_dp .or. b == 0.0_dp) then
        combine_code = 0.0_dp
      else
        combine_code = sqrt(a)*sqrt(b)
      end if
    case default
      combine_code = min(a, b)
    end select
  end function combine_code

  !> One entry per &body group of a validated deck: the group's own restitution and
  !> friction (group_restitution(k), group_friction(k): the &body values), or the &contact
  !> value where the group gives -1 (the default).
  subroutine init(self, contact, group_restitution, group_friction)
    class(material_table_t), intent(inout) :: self
    type(contact_config_t), intent(in) :: contact
    real(dp), intent(in) :: group_restitution(:), group_friction(:)
    integer :: k, n
    call self%free()
    self%restitution_rule = rule_code(contact%restitution_rule)
    self%friction_rule = rule_code(contact%friction_rule)
    n = size(group_restitution)
    allocate (self%restitution(n), self%friction(n))
    do k = 1, n
      ! The reader allows only -1 or a valid value, so any negative value means "unset".
      if (group_restitution(k) >= 0.0_dp) then
        self%restitution(k) = group_restitution(k)
      else
        self%restitution(k) = contact%restitution
      end if
      if (group_friction(k) >= 0.0_dp) then
        self%friction(k) = group_friction(k)
      else
        self%friction(k) = contact%friction
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
    pair_restitution = combine_code(self%restitution(group_a), self%restitution(group_b), self%restitution_rule)
  end function pair_restitution

  !> mu of a contact between a body of group group_a and one of group group_b [-].
  pure real(dp) function pair_friction(self, group_a, group_b)
    class(material_table_t), intent(in) :: self
    integer, intent(in) :: group_a, group_b
    pair_friction = combine_code(self%friction(group_a), self%friction(group_b), self%friction_rule)
  end function pair_friction

end module contact_material
