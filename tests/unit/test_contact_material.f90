!> contact_material: the pair rules (defaults e: the smaller; mu: the geometric mean, exact
!> for one material and zero with a frictionless body, no overflow for extreme valid
!> values; the other rules min, max, mean, each exact for one material), and
!> the per-group table filled from a deck (a group's own value, or &contact's for -1, fixed
!> bodies included). Values are compared exactly where the rule is exact (min, equal
!> inputs, a zero factor) and to a few ulps where a square root is taken.
program test_contact_material
  use kinds, only: dp
  use input_config, only: deck_t, RULE_MIN, RULE_MAX, RULE_MEAN, RULE_GEOMETRIC
  use contact_material, only: combined_restitution, combined_friction, material_table_t
  use assertions
  implicit none
  type(deck_t) :: deck
  type(material_table_t) :: table
  ! sqrt(a) sqrt(b): two correctly rounded square roots and a product, each within half an
  ! ulp, so the result is within ~1.5 ulp of the true geometric mean: 4 eps is safe.
  real(dp), parameter :: tol = 4.0_dp*epsilon(1.0_dp)
  real(dp) :: mu
  integer :: i, j, r
  character(len=*), parameter :: rules(4) = [character(len=9) :: RULE_MIN, RULE_MAX, RULE_MEAN, RULE_GEOMETRIC]

  ! Restitution: the smaller, symmetric, the same material keeps its e.
  call check(combined_restitution(0.9_dp, 0.3_dp) == 0.3_dp, 'e: the smaller of the two')
  call check(combined_restitution(0.3_dp, 0.9_dp) == 0.3_dp, 'e: symmetric')
  call check(combined_restitution(0.55_dp, 0.55_dp) == 0.55_dp, 'e: one material keeps its e')
  call check(combined_restitution(0.0_dp, 1.0_dp) == 0.0_dp, 'e: a perfectly plastic body makes the pair plastic')
  call check(combined_restitution(1.0_dp, 1.0_dp) == 1.0_dp, 'e: two elastic bodies stay elastic')

  ! Friction: the geometric mean.
  call check_close(combined_friction(0.2_dp, 0.8_dp), 0.4_dp, tol, 'mu: sqrt(0.2 * 0.8) = 0.4')
  call check_close(combined_friction(0.5_dp, 2.0_dp), 1.0_dp, tol, 'mu: sqrt(0.5 * 2) = 1')
  call check(combined_friction(0.2_dp, 0.8_dp) == combined_friction(0.8_dp, 0.2_dp), 'mu: symmetric')
  call check(combined_friction(0.0_dp, 5.0_dp) == 0.0_dp .and. combined_friction(5.0_dp, 0.0_dp) == 0.0_dp, &
             'mu: a frictionless body makes the pair frictionless')
  ! 0.3 is not a square: sqrt(0.3)**2 rounds to 0.30000000000000004, so "one material keeps
  ! its mu" needs the equal case to be exact, not merely close.
  do i = 1, 20
    mu = 0.1_dp*real(i, dp) + 0.05_dp
    call check(combined_friction(mu, mu) == mu, 'mu: one material keeps its mu exactly')
  end do
  ! Between the two values, and no overflow or underflow for extreme valid deck values
  ! (the product 1e300 * 1e200 would overflow and trap in the debug build).
  mu = combined_friction(1.0e300_dp, 1.0e200_dp)
  call check_close(mu, 1.0e250_dp, tol, 'mu: 1e300 and 1e200 give 1e250, no overflow')
  mu = combined_friction(1.0e-300_dp, 1.0e-200_dp)
  call check_close(mu, 1.0e-250_dp, tol, 'mu: 1e-300 and 1e-200 give 1e-250, no underflow')
  call check(combined_friction(0.1_dp, 3.0_dp) > 0.1_dp .and. combined_friction(0.1_dp, 3.0_dp) < 3.0_dp, &
             'mu: between the two values')

  ! The table: group 1 a fixed floor with its own e and mu, group 2 only its own e,
  ! group 3 only its own mu, group 4 neither (the &contact values 0.6 and 0.25).
  deck%contact%restitution = 0.6_dp
  deck%contact%friction = 0.25_dp
  deck%n_bodies = 4
  allocate (deck%bodies(4))
  deck%bodies(1)%fixed = .true.
  deck%bodies(1)%restitution = 0.2_dp
  deck%bodies(1)%friction = 0.0_dp
  deck%bodies(2)%restitution = 0.9_dp
  deck%bodies(3)%friction = 1.0_dp
  call check(deck%bodies(4)%restitution == -1.0_dp .and. deck%bodies(4)%friction == -1.0_dp, &
             'body_spec_t material defaults are -1 (the &contact value)')
  call table%init(deck%contact, deck%bodies%restitution, deck%bodies%friction)
  call check(size(table%restitution) == 4 .and. size(table%friction) == 4, 'one entry per &body group')
  call check(all(table%restitution == [0.2_dp, 0.9_dp, 0.6_dp, 0.6_dp]), 'restitution per group, -1 -> &contact''s')
  call check(all(table%friction == [0.0_dp, 0.25_dp, 1.0_dp, 0.25_dp]), 'friction per group, -1 -> &contact''s')
  call check(table%pair_restitution(1, 2) == 0.2_dp, 'floor (0.2) and group 2 (0.9): e = 0.2')
  call check(table%pair_restitution(2, 3) == 0.6_dp, 'group 2 (0.9) and group 3 (&contact 0.6): e = 0.6')
  call check(table%pair_restitution(2, 2) == 0.9_dp, 'two bodies of group 2: their own e')
  call check(table%pair_friction(1, 3) == 0.0_dp, 'frictionless floor: mu = 0 with any body')
  call check_close(table%pair_friction(3, 4), 0.5_dp, tol, 'group 3 (1.0) and group 4 (0.25): mu = 0.5')
  call check(table%pair_friction(4, 4) == 0.25_dp, 'two bodies of group 4: the &contact mu')
  do i = 1, 4
    do j = 1, 4
      call check(table%pair_restitution(i, j) == table%pair_restitution(j, i) .and. &
                 table%pair_friction(i, j) == table%pair_friction(j, i), 'pair rules are symmetric')
    end do
  end do
  ! The other rules, by name: min, max, mean (0.5 a + 0.5 b: exact for these binary
  ! fractions), and each returns one material's value exactly, and stays symmetric.
  call check(combined_restitution(0.9_dp, 0.5_dp, RULE_MIN) == 0.5_dp, 'e, min: 0.5')
  call check(combined_restitution(0.9_dp, 0.5_dp, RULE_MAX) == 0.9_dp, 'e, max: 0.9')
  call check(combined_restitution(0.75_dp, 0.25_dp, RULE_MEAN) == 0.5_dp, 'e, mean: (0.75 + 0.25)/2')
  call check(combined_restitution(1.0_dp, 0.0_dp, RULE_MEAN) == 0.5_dp, 'e, mean: stays in [0, 1]')
  call check(combined_friction(0.2_dp, 0.8_dp, RULE_MIN) == 0.2_dp, 'mu, min')
  call check(combined_friction(0.2_dp, 0.8_dp, RULE_MAX) == 0.8_dp, 'mu, max')
  call check(combined_friction(0.25_dp, 0.75_dp, RULE_MEAN) == 0.5_dp, 'mu, mean')
  call check(combined_friction(0.0_dp, 0.8_dp, RULE_MEAN) == 0.4_dp, 'mu, mean: a frictionless body halves, not zeroes')
  call check(combined_friction(0.0_dp, 0.8_dp, RULE_GEOMETRIC) == 0.0_dp, 'mu, geometric by name: zero wins')
  call check(combined_friction(1.0e300_dp, 1.0e308_dp, RULE_MEAN) <= huge(1.0_dp), 'mu, mean: no overflow')
  do r = 1, size(rules)
    call check(combined_restitution(0.3_dp, 0.3_dp, trim(rules(r))) == 0.3_dp .and. &
               combined_friction(0.1_dp, 0.1_dp, trim(rules(r))) == 0.1_dp, &
               'rule '//trim(rules(r))//': one material keeps its value exactly')
    call check(combined_friction(0.1_dp, 0.7_dp, trim(rules(r))) == combined_friction(0.7_dp, 0.1_dp, trim(rules(r))), &
               'rule '//trim(rules(r))//': symmetric')
  end do
  ! The table applies &contact's rules.
  deck%contact%restitution_rule = RULE_MAX
  deck%contact%friction_rule = RULE_MIN
  call table%init(deck%contact, deck%bodies%restitution, deck%bodies%friction)
  call check(table%pair_restitution(1, 2) == 0.9_dp, 'table, restitution_rule max: floor 0.2, group 2 0.9 -> 0.9')
  call check(table%pair_friction(3, 4) == 0.25_dp, 'table, friction_rule min: 1.0 and 0.25 -> 0.25')
  deck%contact%restitution_rule = RULE_MEAN
  deck%contact%friction_rule = RULE_MEAN
  call table%init(deck%contact, deck%bodies%restitution, deck%bodies%friction)
  call check_close(table%pair_restitution(1, 2), 0.55_dp, tol, 'table, restitution_rule mean: (0.2 + 0.9)/2')
  call check(table%pair_friction(3, 4) == 0.625_dp, 'table, friction_rule mean: (1.0 + 0.25)/2')
  deck%contact%restitution_rule = RULE_MIN
  deck%contact%friction_rule = RULE_GEOMETRIC

  ! Re-initialising replaces the table (a restart builds it again).
  deck%bodies(2)%restitution = -1.0_dp
  call table%init(deck%contact, deck%bodies%restitution, deck%bodies%friction)
  call check(table%restitution(2) == 0.6_dp, 'init again: group 2 now takes &contact''s e')
  call table%free()
  call check(.not. allocated(table%restitution) .and. .not. allocated(table%friction), 'free deallocates')

  call test_finish()
end program test_contact_material
