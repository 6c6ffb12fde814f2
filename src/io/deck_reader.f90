!> Reads and validates a namelist deck into a deck_t (docs/input.md), after FDS: one reader
!> per namelist group, defaults reset before every read (for each &body too), the deck's
!> line and the group (and which &body, by index and name) in every error.
!>
!> How a deck is read:
!>  1. The file is read into memory once; comments ('!' to the end of the line, outside
!>     quotes) are blanked.
!>  2. A scan finds every group ('&name' up to the '/' that closes it, respecting quotes) and
!>     its lines. Unknown group names, text outside groups, unclosed groups, repeated single
!>     groups, a missing &run or no &body are errors.
!>  3. Each group's text is split into assignments 'variable[(i[:j])] = values' and checked
!>     before Fortran sees it: known variable, subscript in range, the right number of values,
!>     each value of the right type and finite, nothing given twice. gfortran's namelist
!>     READ silently accepts some wrong input (t_end = abc leaves t_end unchanged; 1e400
!>     traps in the debug build), so this check is what makes "never silently accepted" true.
!>  4. A Fortran namelist READ from an internal file holding just that group's text fills
!>     the values (iostat/iomsg; should it still fail, gfortran's message is translated).
!>  5. The values are checked: required, ranges, shape-specific variables, paths.
!> The first error found ends the read; its message is
!>  '<deck>:<line>: &group: <what>'  or  '<deck>:<line>: &body #k 'name': <what>'.
!>
!> Where each part lives (src/io/deck/): namelist_source holds steps 1 to 3, the
!> translation of a failed READ and the messages, shared by all groups; run_group,
!> integrator_group, contact_group, output_group and body_group each hold one group's
!> variables, defaults, namelist READ (step 4) and rules (step 5), and its text in the
!> effective deck; deck_paths resolves paths against the deck's folder. This module is the
!> entry point: it reads the groups in deck order, checks the bodies together and writes
!> the effective deck.
module deck_reader
  use kinds, only: i8
  use error_status, only: error_t, ERR_INPUT
  use string_utils, only: str, dirname
  use input_config, only: deck_t, body_spec_t
  use namelist_source, only: DECK_AUTO, source_t, load_source, scan_groups, check_group_structure
  use deck_paths, only: resolve_path, absolute_path
  use run_group, only: read_run_group, write_run_group
  use integrator_group, only: read_integrator_group, write_integrator_group
  use contact_group, only: read_contact_group, write_contact_group
  use output_group, only: read_output_group, write_output_group
  use parallel_group, only: read_parallel_group, write_parallel_group
  use body_group, only: read_body_group, write_body_group
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: read_deck, share_block, check_deck_bodies, write_effective_deck, effective_deck_lines, DECK_AUTO

contains

  !> Reads the deck at path, checks it and fills deck (defaults where nothing is given).
  !> On failure err holds one message '<path>:<line>: <group>: <what>' (code ERR_INPUT, or
  !> ERR_IO if the file cannot be read) and deck is incomplete. err must not hold a failure
  !> on entry (the call then returns at once).
  !> Relative paths in the deck (mesh_file, output dir) are stored resolved against the
  !> deck's folder, as absolute paths.
  subroutine read_deck(path, deck, err, share, failed_group)
    character(len=*), intent(in) :: path
    type(deck_t), intent(out) :: deck
    type(error_t), intent(inout) :: err
    !> (rank, ranks): read only this rank's block of the &body groups (n_bodies rank / ranks
    !> + 1 .. n_bodies (rank + 1) / ranks), the others left at their defaults but for their
    !> line, and skip the checks of all bodies together (check_deck_bodies, once the blocks
    !> are gathered: shared_deck)
    integer, intent(in), optional :: share(2)
    !> the group whose reading failed (its number in the deck; 0: none, or before the groups)
    integer, intent(out), optional :: failed_group
    type(source_t) :: src
    integer :: k, i_body, first_body, last_body

    if (present(failed_group)) failed_group = 0
    if (err%failed()) return   ! an error already pending is not overwritten
    call load_source(path, src, err)
    if (err%failed()) return
    call scan_groups(src, err)
    if (err%failed()) return
    call check_group_structure(src, err)
    if (err%failed()) return

    deck%path = path
    deck%folder = absolute_path(dirname(path))
    deck%n_bodies = count([(src%groups(k)%name == 'body', k=1, src%n_groups)])
    allocate (deck%bodies(deck%n_bodies))
    first_body = 1
    last_body = deck%n_bodies
    if (present(share)) then
      call share_block(deck%n_bodies, share, first_body, last_body)
    end if
    i_body = 0
    ! Groups are read in deck order so that the first error reported is the first in the file.
    do k = 1, src%n_groups
      select case (src%groups(k)%name)
      case ('run')
        call read_run_group(src, src%groups(k), deck%run, err)
      case ('integrator')
        call read_integrator_group(src, src%groups(k), deck%integrator, err)
      case ('contact')
        call read_contact_group(src, src%groups(k), deck%contact, err)
      case ('output')
        call read_output_group(src, src%groups(k), deck%folder, deck%output, err)
      case ('parallel')
        call read_parallel_group(src, src%groups(k), deck%parallel, err)
      case ('body')
        i_body = i_body + 1
        if (i_body >= first_body .and. i_body <= last_body) then
          call read_body_group(src, src%groups(k), i_body, deck%folder, deck%bodies(i_body), err)
        else
          deck%bodies(i_body)%line = src%groups(k)%first_line
        end if
      end select
      if (err%failed()) then
        if (present(failed_group)) failed_group = k
        return
      end if
    end do
    if (.not. present(share)) call check_deck_bodies(deck, err)
    if (err%failed()) return
    ! Without &output the default dir still resolves against the deck's folder (a no-op when
    ! &output resolved it already: the path is absolute).
    deck%output%dir = resolve_path(deck%folder, deck%output%dir)
  end subroutine read_deck

  !> The &body groups first..last (of n) that rank share(1) of share(2) parses in read_deck's
  !> share: contiguous blocks in rank order, so that their concatenation is the deck's order.
  pure subroutine share_block(n, share, first, last)
    integer, intent(in) :: n, share(2)
    integer, intent(out) :: first, last
    first = int(int(n, i8)*share(1)/share(2)) + 1
    last = int(int(n, i8)*(share(1) + 1)/share(2))
  end subroutine share_block

  !> Checks across bodies: distinct names, a total count that fits an integer. Names are
  !> compared after sorting (n log n: decks written by tools may hold many &body groups).
  subroutine check_deck_bodies(deck, err)
    type(deck_t), intent(in) :: deck
    type(error_t), intent(inout) :: err
    integer, allocatable :: order(:)
    integer :: k, first, second
    integer(i8) :: total
    if (deck%n_bodies == 0) return
    order = [(k, k=1, deck%n_bodies)]
    call sort_by_name(deck%bodies, order)
    do k = 2, deck%n_bodies
      if (deck%bodies(order(k))%name == deck%bodies(order(k - 1))%name) then
        first = min(order(k), order(k - 1))
        second = max(order(k), order(k - 1))
        call err%set(ERR_INPUT, deck%path//':'//str(deck%bodies(second)%line)//': &body #'//str(second)//' '''// &
                     trim(deck%bodies(second)%name)//''': name '''//trim(deck%bodies(second)%name)// &
                     ''' is already used by &body #'//str(first)//' (line '//str(deck%bodies(first)%line)//')')
        return
      end if
    end do
    total = 0
    do k = 1, deck%n_bodies
      total = total + product(int(deck%bodies(k)%copies, i8))
    end do
    if (total > int(huge(0), i8)) then
      call err%set(ERR_INPUT, deck%path//': the deck describes '//str(total)//' bodies, more than '//str(huge(0)))
    end if
  end subroutine check_deck_bodies

  !> Stable bottom-up merge sort of order(:) by bodies(order(:))%name.
  subroutine sort_by_name(bodies, order)
    type(body_spec_t), intent(in) :: bodies(:)
    integer, intent(inout) :: order(:)
    integer, allocatable :: work(:)
    integer :: width, lo, mid, hi, i, j, k, n
    logical :: take_left
    n = size(order)
    allocate (work(n))
    width = 1
    do while (width < n)
      lo = 1
      do while (lo <= n)
        mid = min(lo + width - 1, n)
        hi = min(lo + 2*width - 1, n)
        i = lo
        j = mid + 1
        do k = lo, hi
          if (i > mid) then
            take_left = .false.
          else if (j > hi) then
            take_left = .true.
          else
            take_left = .not. llt(bodies(order(j))%name, bodies(order(i))%name)
          end if
          if (take_left) then
            work(k) = order(i)
            i = i + 1
          else
            work(k) = order(j)
            j = j + 1
          end if
        end do
        lo = hi + 1
      end do
      order = work
      width = 2*width
    end do
  end subroutine sort_by_name

  !> Writes deck as a namelist deck with every variable, defaults filled in, that read_deck
  !> reads back to the same deck_t (apart from path, folder and body lines). Values that are
  !> "auto" are written as -1 (DECK_AUTO); variables that do not apply (a box's radius, the
  !> mass of a body given by density) are written as comments. Reals are written with the
  !> fewest digits that read back exactly; paths are absolute.
  subroutine write_effective_deck(deck, unit)
    type(deck_t), intent(in) :: deck
    integer, intent(in) :: unit      !< an open formatted unit
    type(deck_sink_t) :: out
    call out%to_unit(unit)
    call write_deck_to(deck, out)
  end subroutine write_effective_deck

  !> write_effective_deck's lines, to a unit or to memory.
  subroutine write_deck_to(deck, out)
    type(deck_t), intent(in) :: deck
    type(deck_sink_t), intent(inout) :: out
    integer :: k
    call out%put('! ricochet effective input: every variable, defaults filled in (docs/input.md)')
    if (allocated(deck%path)) call out%put('! deck: '//deck%path)
    call write_settings(deck, out)
    if (.not. allocated(deck%bodies)) return
    do k = 1, deck%n_bodies
      call write_body_group(deck%bodies(k), k, out)
    end do
  end subroutine write_deck_to

  !> The groups of the run's settings (all but the bodies) of the effective deck.
  subroutine write_settings(deck, out)
    type(deck_t), intent(in) :: deck
    type(deck_sink_t), intent(inout) :: out
    call write_run_group(deck%run, out)
    call write_integrator_group(deck%integrator, out)
    call write_contact_group(deck%contact, out)
    call write_output_group(deck%output, out)
    call write_parallel_group(deck%parallel, out)
  end subroutine write_settings

  !> The effective deck as 'variable = value' lines under their group headers ('&run',
  !> '&body #3', '/'), comments dropped: what a checkpoint stores, so that a restart can
  !> name every variable its deck changed. lines are as wide as the longest: a line per
  !> variable and body makes 540,000 lines for 27,000 bodies, 600 MB at the full width of
  !> line_length (and as long to fill), 40 MB so.
  !> groups, when present: only the lines of body groups groups(1) to groups(2), and those
  !> of the run's settings (&run to &parallel) only if settings is true: a share of the
  !> whole (a rank's; the shares in order are the whole).
  subroutine effective_deck_lines(deck, lines, groups, settings)
    type(deck_t), intent(in) :: deck
    character(len=:), allocatable, intent(out) :: lines(:)
    integer, intent(in), optional :: groups(2)
    logical, intent(in), optional :: settings
    type(deck_sink_t) :: out
    integer :: k
    ! (in memory: comment lines and trailing comments dropped, '&body ! #3' as '&body #3')
    call out%to_memory()
    if (present(groups)) then
      if (present(settings)) then
        if (settings) call write_settings(deck, out)
      end if
      if (allocated(deck%bodies)) then
        do k = max(1, groups(1)), min(deck%n_bodies, groups(2))
          call write_body_group(deck%bodies(k), k, out)
        end do
      end if
    else
      call write_deck_to(deck, out)
    end if
    call out%take_lines(lines)
  end subroutine effective_deck_lines


end module deck_reader
