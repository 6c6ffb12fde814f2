!> The deck of a run on several ranks, its &body groups parsed in shares: every rank reads
!> the file and its settings, parses its block of the body groups (deck_reader read_deck's
!> share) and the blocks are gathered, so that every rank holds the whole deck, the same as
!> one rank reading it alone, bit for bit. Parsing the groups was a fifth of a 100,000-body
!> run on every rank whatever their number (docs/benchmarks.md, "The deck read in shares").
!> Errors are the first in the file on every rank, whichever rank's block holds it: the
!> group numbers of the failures are reduced to the first and that rank's message is sent
!> to all, so that rank 0 says it as when one rank reads (the app's fail).
module shared_deck
  use kinds, only: i8
  use error_status, only: error_t
  use input_config, only: deck_t, body_spec_t
  use deck_reader, only: read_deck, share_block, check_deck_bodies
  use parallel_env, only: parallel_t
  implicit none
  private
  public :: read_deck_shared

contains

  subroutine read_deck_shared(par, path, deck, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    type(deck_t), intent(out) :: deck
    type(error_t), intent(inout) :: err
    integer(i8) :: first_failed, speaker
    character(len=:), allocatable :: message
    integer :: failed, code, first, last
    type(body_spec_t) :: probe
    ! (a spec travels as its bytes: a whole number of them, no allocatable component;
    ! otherwise every rank parses every group, as one rank does)
    if (par%n_ranks == 1 .or. mod(storage_size(probe), 8) /= 0) then
      call read_deck(path, deck, err)
      return
    end if
    call read_deck(path, deck, err, share=[par%rank, par%n_ranks], failed_group=failed)
    ! (a failure before the groups, such as an unreadable file, is every rank's: group 0)
    first_failed = par%min(merge(int(failed, i8), huge(1_i8), err%failed()))
    if (first_failed < huge(1_i8)) then
      speaker = par%min(merge(int(par%rank, i8), huge(1_i8), err%failed() .and. failed == first_failed))
      message = ''
      code = 0
      if (par%rank == speaker) then
        message = err%message
        code = err%code
      end if
      call par%bcast(message, int(speaker))
      call par%bcast(code, int(speaker))
      call err%clear()
      call err%set(code, message)
      return
    end if
    ! this rank's block of body specs, read in place, gathered in place in rank order: the
    ! deck's order (a body_spec_t holds no allocatable: its bytes are the whole of it)
    call share_block(deck%n_bodies, [par%rank, par%n_ranks], first, last)
    call par%allgather_blocks_in_place(deck%bodies, storage_size(probe)/8, max(0, last - first + 1))
    call check_deck_bodies(deck, err)
  end subroutine read_deck_shared

end module shared_deck
