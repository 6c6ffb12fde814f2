!> free_flight's undo journal (the cross-rank window's save): after start_journal, any mix
!> of changes to the records (new anchors, releases, loads set and cleared, records set from
!> other bodies, the same body changed many times) is undone by roll_back bit for bit (every
!> record compared as its anchor_words); the journal goes on after a roll_back (a second
!> one returns to the same state); rows appended by grow while journaling are left alone;
!> after stop_journal, roll_back undoes nothing (the negative control: the changed records
!> then differ from the saved ones, so the comparison can fail).
program test_flight_journal
  use kinds, only: dp, i8
  use body_state, only: bodies_t
  use free_flight, only: free_flight_t
  use input_config, only: integrator_config_t, ROTATION_EXACT
  use random_stream, only: random_stream_t
  use body_fixtures, only: filled_bodies
  use assertions
  implicit none

  integer, parameter :: n_bodies = 40
  type(bodies_t) :: bodies
  type(free_flight_t) :: flight
  type(integrator_config_t) :: config
  type(random_stream_t) :: rng
  integer(i8), allocatable :: before(:, :), after(:, :)
  integer :: i

  config%rotation = ROTATION_EXACT
  call filled_bodies(n_bodies, 0, 5, 1000_i8, bodies)
  call flight%init(n_bodies, config)
  do i = 1, n_bodies
    call flight%anchor_at(bodies, i, 0.25_dp)
  end do
  call flight%set_load(3, [0.0_dp, -9.81_dp, 1.0_dp])
  call rng%init(17)
  call flight%pack_anchors(n_bodies, before)

  call flight%start_journal()
  call change_records(200)
  call flight%pack_anchors(n_bodies, after)
  call check(any(after /= before), 'the changes changed records (else the comparisons below prove nothing)')
  call flight%roll_back()
  call flight%pack_anchors(n_bodies, after)
  call check(all(after == before), 'roll_back: every record bit for bit as at start_journal')
  call check(flight%n_journal == 0, 'roll_back empties the journal')

  ! the journal goes on: changes after a roll_back are undone by the next one
  call change_records(50)
  call flight%roll_back()
  call flight%pack_anchors(n_bodies, after)
  call check(all(after == before), 'a second roll_back returns to the same state')

  ! rows appended while journaling (ghosts arriving) keep what they are given
  call flight%grow(n_bodies + 2)
  call flight%set_record(n_bodies + 1, before(:, 7))
  call change_records(30)
  call flight%roll_back()
  call flight%pack_anchors(n_bodies, after)
  call check(all(after == before), 'roll_back after grow: the old rows as at start_journal')

  ! negative control: no journal, nothing undone
  call flight%stop_journal()
  call change_records(30)
  call flight%roll_back()
  call flight%pack_anchors(n_bodies, after)
  call check(any(after /= before), 'after stop_journal roll_back undoes nothing')
  call test_finish()

contains

  !> n random changes of random records, as a window's events make them.
  subroutine change_records(n)
    integer, intent(in) :: n
    integer :: k, j, other
    integer(i8), allocatable :: words(:, :)
    do k = 1, n
      j = 1 + int(rng%uniform()*n_bodies)
      j = min(j, n_bodies)
      select case (mod(k, 5))
      case (0)
        bodies%v(:, j) = bodies%v(:, j) + [0.5_dp, -0.25_dp, 0.125_dp]
        bodies%w(:, j) = -bodies%w(:, j)
        call flight%anchor_at(bodies, j, 0.25_dp + 0.01_dp*k)
      case (1)
        call flight%release(j)
      case (2)
        call flight%set_load(j, [0.0_dp, 0.0_dp, -1.0_dp*k])
      case (3)
        call flight%clear_load(j)
      case default
        other = 1 + mod(j + 11, n_bodies)
        call flight%pack_anchors(0, words, [other])
        call flight%set_record(j, words(:, 1))
      end select
    end do
  end subroutine change_records

end program test_flight_journal
