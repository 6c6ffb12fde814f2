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
module deck_reader
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use, intrinsic :: iso_c_binding, only: c_char, c_size_t, c_ptr, c_associated, c_null_char
  use kinds, only: dp, i8
  use constants, only: pi, unit_quaternion_tolerance
  use error_status, only: error_t, ERR_INPUT, ERR_IO
  use string_utils, only: str, lower, dirname, is_absolute_path
  use input_config, only: deck_t, run_config_t, integrator_config_t, contact_config_t, &
                          output_config_t, body_spec_t, ROTATION_NEWMARK, ROTATION_EXACT
  implicit none
  private
  public :: read_deck, write_effective_deck, DECK_AUTO

  !> Value meaning "auto" (min_separation, rest_speed, output intervals, inertia: derived at
  !> set-up) or, for a body's restitution and friction, "the &contact value". Given exactly
  !> in a deck it means the same, so an effective deck reads back unchanged.
  real(dp), parameter :: DECK_AUTO = -1.0_dp

  integer, parameter :: V_REAL = 1, V_INTEGER = 2, V_LOGICAL = 3, V_CHARACTER = 4
  integer, parameter :: T_WORD = 1, T_STRING = 2, T_EQUALS = 3, T_COMMA = 4
  integer, parameter :: MAX_ELEMENTS = 4     !< largest array in a group (orientation)

  !> One namelist variable: name, value type, number of elements, character length.
  type :: var_spec_t
    character(len=24) :: name = ''
    integer :: kind = V_REAL
    integer :: n = 1
    integer :: length = 0
  end type var_spec_t

  type(run_config_t), parameter :: run_default = run_config_t()
  type(integrator_config_t), parameter :: integrator_default = integrator_config_t()
  type(output_config_t), parameter :: output_default = output_config_t()
  type(body_spec_t), parameter :: body_default = body_spec_t()

  type(var_spec_t), parameter :: run_vars(4) = [ &
    var_spec_t('title', V_CHARACTER, 1, len(run_default%title)), var_spec_t('t_end', V_REAL, 1, 0), &
    var_spec_t('dt_max', V_REAL, 1, 0), var_spec_t('gravity', V_REAL, 3, 0)]
  type(var_spec_t), parameter :: integrator_vars(5) = [ &
    var_spec_t('newmark_beta', V_REAL, 1, 0), var_spec_t('newmark_gamma', V_REAL, 1, 0), &
    var_spec_t('rotation_tolerance', V_REAL, 1, 0), var_spec_t('rotation_max_iterations', V_INTEGER, 1, 0), &
    var_spec_t('rotation', V_CHARACTER, 1, len(integrator_default%rotation))]
  type(var_spec_t), parameter :: contact_vars(6) = [ &
    var_spec_t('restitution', V_REAL, 1, 0), var_spec_t('friction', V_REAL, 1, 0), &
    var_spec_t('min_separation', V_REAL, 1, 0), var_spec_t('rest_speed', V_REAL, 1, 0), &
    var_spec_t('sleep_speed', V_REAL, 1, 0), var_spec_t('sleep_time', V_REAL, 1, 0)]
  type(var_spec_t), parameter :: output_vars(7) = [ &
    var_spec_t('dir', V_CHARACTER, 1, len(output_default%dir)), var_spec_t('interval', V_REAL, 1, 0), &
    var_spec_t('checkpoint_interval', V_REAL, 1, 0), var_spec_t('progress_interval', V_REAL, 1, 0), &
    var_spec_t('history_interval', V_REAL, 1, 0), var_spec_t('write_frames', V_LOGICAL, 1, 0), &
    var_spec_t('check_overlaps', V_LOGICAL, 1, 0)]
  type(var_spec_t), parameter :: body_vars(26) = [ &
    var_spec_t('name', V_CHARACTER, 1, len(body_default%name)), &
    var_spec_t('shape', V_CHARACTER, 1, len(body_default%shape)), &
    var_spec_t('radius', V_REAL, 1, 0), var_spec_t('size', V_REAL, 3, 0), &
    var_spec_t('segments', V_INTEGER, 1, 0), var_spec_t('minor_radius', V_REAL, 1, 0), &
    var_spec_t('tube_segments', V_INTEGER, 1, 0), var_spec_t('thickness', V_REAL, 1, 0), &
    var_spec_t('mesh_file', V_CHARACTER, 1, len(body_default%mesh_file)), &
    var_spec_t('scale', V_REAL, 1, 0), var_spec_t('density', V_REAL, 1, 0), var_spec_t('mass', V_REAL, 1, 0), &
    var_spec_t('position', V_REAL, 3, 0), var_spec_t('orientation', V_REAL, 4, 0), &
    var_spec_t('velocity', V_REAL, 3, 0), var_spec_t('angular_velocity', V_REAL, 3, 0), &
    var_spec_t('fixed', V_LOGICAL, 1, 0), var_spec_t('copies', V_INTEGER, 3, 0), &
    var_spec_t('spacing', V_REAL, 3, 0), var_spec_t('seed', V_INTEGER, 1, 0), &
    var_spec_t('jitter_position', V_REAL, 1, 0), var_spec_t('jitter_angle', V_REAL, 1, 0), &
    var_spec_t('jitter_velocity', V_REAL, 1, 0), var_spec_t('inertia', V_REAL, 3, 0), &
    var_spec_t('restitution', V_REAL, 1, 0), var_spec_t('friction', V_REAL, 1, 0)]

  character(len=*), parameter :: known_groups = '&run, &integrator, &contact, &output, &body'
  character(len=10), parameter :: group_names(5) = [character(len=10) :: &
    'run', 'integrator', 'contact', 'output', 'body']
  character(len=11), parameter :: shape_names(7) = [character(len=11) :: 'sphere', 'box', 'cylinder', &
    'tetrahedron', 'torus', 'l_prism', 'mesh']
  character(len=*), parameter :: known_shapes = 'sphere, box, cylinder, tetrahedron, torus, l_prism, mesh'

  type :: token_t
    integer :: kind = 0
    character(len=:), allocatable :: text    !< words as written (blanks removed); strings unquoted
    integer :: line = 0
  end type token_t

  !> A group found by the scan: '&' at (first_line, first_col), '/' at (last_line, last_col).
  type :: group_t
    character(len=:), allocatable :: name    !< lower case, without '&'
    integer :: first_line = 0, first_col = 0
    integer :: last_line = 0, last_col = 0
  end type group_t

  !> The deck in memory: its lines with comments and tabs blanked.
  type :: source_t
    character(len=:), allocatable :: path
    character(len=:), allocatable :: code(:)
    integer :: n_lines = 0
    integer :: n_groups = 0
    type(group_t), allocatable :: groups(:)
  end type source_t

  !> One group being read: the text handed to the namelist READ, its variables, and which
  !> elements the deck gives and on which line.
  type :: group_input_t
    character(len=:), allocatable :: deck_path
    character(len=:), allocatable :: label         !< '&run' or '&body #3 ''ball'''
    character(len=:), allocatable :: name          !< group name, lower case
    integer :: line = 0                            !< line of the '&'
    character(len=:), allocatable :: text(:)       !< the group alone, one record per deck line
    type(var_spec_t), allocatable :: specs(:)
    integer, allocatable :: given_line(:, :)       !< (MAX_ELEMENTS, spec): 0 where not given
  end type group_input_t

contains

  !> Reads the deck at path, checks it and fills deck (defaults where nothing is given).
  !> On failure err holds one message '<path>:<line>: <group>: <what>' (code ERR_INPUT, or
  !> ERR_IO if the file cannot be read) and deck is incomplete. err must not hold a failure
  !> on entry (the call then returns at once).
  !> Relative paths in the deck (mesh_file, output dir) are stored resolved against the
  !> deck's folder, as absolute paths.
  subroutine read_deck(path, deck, err)
    character(len=*), intent(in) :: path
    type(deck_t), intent(out) :: deck
    type(error_t), intent(inout) :: err
    type(source_t) :: src
    integer :: k, i_body

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
      case ('body')
        i_body = i_body + 1
        call read_body_group(src, src%groups(k), i_body, deck%folder, deck%bodies(i_body), err)
      end select
      if (err%failed()) return
    end do
    call check_bodies_together(src, deck, err)
    if (err%failed()) return
    ! Without &output the default dir still resolves against the deck's folder (a no-op when
    ! &output resolved it already: the path is absolute).
    deck%output%dir = resolve_path(deck%folder, deck%output%dir)
  end subroutine read_deck

  ! ---------------------------------------------------------------------------------------
  ! The file and its groups
  ! ---------------------------------------------------------------------------------------

  !> Reads the whole file at once and splits it into lines (LF or CR LF); tabs become blanks.
  subroutine load_source(path, src, err)
    character(len=*), intent(in) :: path
    type(source_t), intent(out) :: src
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: bytes
    character(len=512) :: msg
    integer :: unit, ios, n_bytes, i, start, n, width, line

    src%path = path
    open (newunit=unit, file=path, access='stream', form='unformatted', action='read', status='old', &
          iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call err%set(ERR_IO, path//': cannot open the deck: '//trim(msg))
      return
    end if
    inquire (unit=unit, size=n_bytes)
    allocate (character(len=max(n_bytes, 0)) :: bytes)
    ios = 0
    if (n_bytes > 0) read (unit, iostat=ios, iomsg=msg) bytes
    close (unit)
    if (ios /= 0) then
      call err%set(ERR_IO, path//': cannot read the deck: '//trim(msg))
      return
    end if

    n = 0
    width = 0
    start = 1
    do i = 1, n_bytes
      if (bytes(i:i) == achar(10)) then
        n = n + 1
        width = max(width, i - start)
        start = i + 1
      end if
    end do
    if (start <= n_bytes) then
      n = n + 1
      width = max(width, n_bytes - start + 1)
    end if
    ! One spare blank column so that every line ends in a blank.
    allocate (character(len=width + 1) :: src%code(max(n, 1)))
    src%code = ''
    src%n_lines = n
    line = 0
    start = 1
    do i = 1, n_bytes + 1
      if (i == n_bytes + 1) then
        if (start > n_bytes) exit
      else if (bytes(i:i) /= achar(10)) then
        cycle
      end if
      line = line + 1
      src%code(line) = bytes(start:i - 1)
      start = i + 1
    end do
    do line = 1, n
      do i = 1, len(src%code)
        if (src%code(line)(i:i) == achar(9) .or. src%code(line)(i:i) == achar(13)) src%code(line)(i:i) = ' '
      end do
    end do
  end subroutine load_source

  !> Finds the groups ('&name' ... '/', quotes respected) and blanks comments. Text outside a
  !> group that is not a comment is an error: a stray word is a mistake, not a remark.
  subroutine scan_groups(src, err)
    type(source_t), intent(inout) :: src
    type(error_t), intent(inout) :: err
    type(group_t) :: current
    type(group_t), allocatable :: grown(:)
    character :: ch
    integer :: line, c, width, name_end, quote_end, last_closed_line, word_end
    integer :: n_body   ! &body groups closed so far
    logical :: inside

    allocate (src%groups(8))
    src%n_groups = 0
    inside = .false.
    last_closed_line = 0
    n_body = 0
    width = len(src%code)
    do line = 1, src%n_lines
      c = 1
      do while (c <= width)
        ch = src%code(line)(c:c)
        if (inside) then
          select case (ch)
          case ("'", '"')
            quote_end = closing_quote(src%code(line), c)
            if (quote_end == 0) then
              call err%set(ERR_INPUT, src%path//':'//str(line)//': '//scan_label(current%name, n_body)// &
                           ': a quoted value is not closed on its line (missing '//ch//')')
              return
            end if
            c = quote_end
          case ('!')
            src%code(line)(c:) = ''
            exit
          case ('/')
            current%last_line = line
            current%last_col = c
            if (src%n_groups == size(src%groups)) then
              allocate (grown(2*size(src%groups)))
              grown(1:src%n_groups) = src%groups(1:src%n_groups)
              call move_alloc(grown, src%groups)
            end if
            src%n_groups = src%n_groups + 1
            src%groups(src%n_groups) = current
            inside = .false.
            last_closed_line = line
            if (current%name == 'body') n_body = n_body + 1
          case ('&')
            name_end = group_name_end(src%code(line), c)
            call err%set(ERR_INPUT, src%path//':'//str(line)//': '//src%code(line)(c:name_end)// &
                         ' starts before '//scan_label(current%name, n_body)//' (line '//str(current%first_line)// &
                         ') is closed with ''/''')
            return
          end select
        else
          select case (ch)
          case (' ')
          case ('!')
            src%code(line)(c:) = ''
            exit
          case ('&')
            name_end = group_name_end(src%code(line), c)
            if (name_end == c) then
              call err%set(ERR_INPUT, src%path//':'//str(line)//': ''&'' without a group name (known groups: '// &
                           known_groups//')')
              return
            end if
            current%name = lower(src%code(line)(c + 1:name_end))
            current%first_line = line
            current%first_col = c
            inside = .true.
            c = name_end
          case default
            word_end = index(src%code(line)(c:), ' ') + c - 2
            if (last_closed_line == line) then
              call err%set(ERR_INPUT, src%path//':'//str(line)//': text after the ''/'' that closes '// &
                           scan_label(current%name, n_body - 1)//': '''//src%code(line)(c:word_end)// &
                           ''' (a ''/'' ends a group: quote values that contain one, e.g. dir = ''out/a'')')
            else
              call err%set(ERR_INPUT, src%path//':'//str(line)//': text outside a namelist group: '''// &
                           src%code(line)(c:word_end)//''' (groups are ''&name ... /''; comments start with ''!'')')
            end if
            return
          end select
        end if
        c = c + 1
      end do
    end do
    if (inside) then
      call err%set(ERR_INPUT, src%path//':'//str(current%first_line)//': '//scan_label(current%name, n_body)// &
                   ' is not closed with ''/'' before the end of the deck')
    end if
  end subroutine scan_groups

  !> '&name', or '&body #k' for the k-th body (n_closed bodies closed before this group).
  pure function scan_label(name, n_closed) result(label)
    character(len=*), intent(in) :: name
    integer, intent(in) :: n_closed
    character(len=:), allocatable :: label
    label = '&'//name
    if (name == 'body') label = label//' #'//str(n_closed + 1)
  end function scan_label

  !> Unknown group names, repeated single groups, a missing &run or no &body.
  subroutine check_group_structure(src, err)
    type(source_t), intent(in) :: src
    type(error_t), intent(inout) :: err
    integer :: k, j, first(size(group_names))
    first = 0
    do k = 1, src%n_groups
      j = findloc(group_names, src%groups(k)%name, dim=1)
      if (j == 0) then
        call err%set(ERR_INPUT, src%path//':'//str(src%groups(k)%first_line)//': unknown group ''&'// &
                     src%groups(k)%name//''''//suggestion(src%groups(k)%name, group_names, '&')// &
                     ' (known groups: '//known_groups//')')
        return
      end if
      if (first(j) /= 0 .and. src%groups(k)%name /= 'body') then
        call err%set(ERR_INPUT, src%path//':'//str(src%groups(k)%first_line)//': &'//src%groups(k)%name// &
                     ' appears again (first at line '//str(first(j))// &
                     '); &run, &integrator, &contact and &output may each appear once')
        return
      end if
      if (first(j) == 0) first(j) = src%groups(k)%first_line
    end do
    if (first(1) == 0) then
      call err%set(ERR_INPUT, src%path//': no &run group: a deck needs &run with t_end and dt_max')
    else if (first(5) == 0) then
      call err%set(ERR_INPUT, src%path//': no &body group: a deck needs at least one body')
    end if
  end subroutine check_group_structure

  !> Position of the closing quote of the string opening at text(start:start) (a doubled
  !> quote is a quote inside the string), 0 if the line ends first.
  pure integer function closing_quote(text, start) result(pos)
    character(len=*), intent(in) :: text
    integer, intent(in) :: start
    character :: q
    integer :: c
    q = text(start:start)
    pos = 0
    c = start + 1
    do while (c <= len(text))
      if (text(c:c) == q) then
        if (c < len(text)) then
          if (text(c + 1:c + 1) == q) then
            c = c + 2
            cycle
          end if
        end if
        pos = c
        return
      end if
      c = c + 1
    end do
  end function closing_quote

  !> Last position of the name following the '&' at text(amp:amp) (amp itself if none).
  pure integer function group_name_end(text, amp) result(last)
    character(len=*), intent(in) :: text
    integer, intent(in) :: amp
    last = amp
    do while (last < len(text))
      if (.not. is_name_char(text(last + 1:last + 1))) exit
      last = last + 1
    end do
  end function group_name_end

  elemental logical function is_name_char(ch)
    character, intent(in) :: ch
    is_name_char = (ch >= 'a' .and. ch <= 'z') .or. (ch >= 'A' .and. ch <= 'Z') .or. &
                   (ch >= '0' .and. ch <= '9') .or. ch == '_'
  end function is_name_char

  ! ---------------------------------------------------------------------------------------
  ! One group: its text, its assignments and their check
  ! ---------------------------------------------------------------------------------------

  !> The group's text alone (other text on its first and last line blanked), ready for the
  !> namelist READ, and an empty record of what is given.
  subroutine open_group(src, group, specs, label, g)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(var_spec_t), intent(in) :: specs(:)
    character(len=*), intent(in) :: label
    type(group_input_t), intent(out) :: g
    integer :: n
    g%deck_path = src%path
    g%label = label
    g%name = group%name
    g%line = group%first_line
    n = group%last_line - group%first_line + 1
    allocate (character(len=len(src%code)) :: g%text(n))
    g%text = src%code(group%first_line:group%last_line)
    if (group%first_col > 1) g%text(1)(1:group%first_col - 1) = ''
    g%text(n)(group%last_col + 1:) = ''
    g%specs = specs
    allocate (g%given_line(MAX_ELEMENTS, size(specs)))
    g%given_line = 0
  end subroutine open_group

  !> Splits the group's text (after '&name', up to '/') into words, quoted strings, '=' and ','.
  subroutine tokenize(g, tokens, n_tokens, err)
    type(group_input_t), intent(inout) :: g
    type(token_t), allocatable, intent(out) :: tokens(:)
    integer, intent(out) :: n_tokens
    type(error_t), intent(inout) :: err
    character :: ch
    integer :: r, c, e, depth, q_end, width, line
    character(len=:), allocatable :: word
    allocate (tokens(16))
    n_tokens = 0
    width = len(g%text)
    c = index(g%text(1), '&') + 1 + len(g%name)
    do r = 1, size(g%text)
      line = g%line + r - 1
      do while (c <= width)
        ch = g%text(r)(c:c)
        select case (ch)
        case (' ')
          c = c + 1
        case (',')
          call push_token(tokens, n_tokens, T_COMMA, ',', line)
          c = c + 1
        case ('=')
          call push_token(tokens, n_tokens, T_EQUALS, '=', line)
          c = c + 1
        case ('/')
          return
        case ("'", '"')
          q_end = closing_quote(g%text(r), c)
          call push_token(tokens, n_tokens, T_STRING, unquote(g%text(r)(c + 1:q_end - 1), ch), line)
          c = q_end + 1
        case default
          e = c
          depth = 0
          do while (e <= width)
            ch = g%text(r)(e:e)
            if (ch == '(') depth = depth + 1
            if (ch == ')') depth = depth - 1
            if (depth == 0 .and. index(' ,=/''"', ch) > 0) exit
            if (ch == '/' .or. ch == '''' .or. ch == '"') exit
            e = e + 1
          end do
          if (depth /= 0) then
            call fail_at(g, err, line, 'unmatched parenthesis in '''//trim(g%text(r)(c:e - 1))//'''')
            return
          end if
          word = without_blanks(g%text(r)(c:e - 1))
          ! gfortran's READ rejects blanks inside a subscript ('size( 3 )'): hand it the
          ! packed form, in place, so that lines stay where they are.
          if (len(word) < e - c) g%text(r)(c:e - 1) = word
          call push_token(tokens, n_tokens, T_WORD, word, line)
          c = e
        end select
      end do
      c = 1
    end do
  end subroutine tokenize

  subroutine push_token(tokens, n_tokens, kind, text, line)
    type(token_t), allocatable, intent(inout) :: tokens(:)
    integer, intent(inout) :: n_tokens
    integer, intent(in) :: kind, line
    character(len=*), intent(in) :: text
    type(token_t), allocatable :: grown(:)
    if (n_tokens == size(tokens)) then
      allocate (grown(2*size(tokens)))
      grown(1:n_tokens) = tokens(1:n_tokens)
      call move_alloc(grown, tokens)
    end if
    n_tokens = n_tokens + 1
    tokens(n_tokens)%kind = kind
    tokens(n_tokens)%text = text
    tokens(n_tokens)%line = line
  end subroutine push_token

  !> Checks every 'designator = values' of the group and records what is given where.
  subroutine check_assignments(g, tokens, n_tokens, err)
    type(group_input_t), intent(inout) :: g
    type(token_t), intent(in) :: tokens(:)
    integer, intent(in) :: n_tokens
    type(error_t), intent(inout) :: err
    integer :: i, i_name, n_items
    integer, allocatable :: items(:)
    logical :: expect_value
    allocate (items(max(n_tokens, 1)))
    i = 1
    do while (i <= n_tokens)
      if (tokens(i)%kind == T_COMMA) then
        i = i + 1
        cycle
      end if
      if (.not. starts_assignment(tokens, n_tokens, i)) then
        select case (tokens(i)%kind)
        case (T_EQUALS)
          call fail_at(g, err, tokens(i)%line, '''='' without a variable name before it')
        case (T_WORD)
          call fail_at(g, err, tokens(i)%line, 'expected ''variable = value'', found '''//tokens(i)%text// &
                       ''' without ''='' after it')
        case default
          call fail_at(g, err, tokens(i)%line, 'expected ''variable = value'', found the text '''// &
                       tokens(i)%text//'''')
        end select
        return
      end if
      i_name = i
      i = i + 2
      n_items = 0
      expect_value = .true.
      do while (i <= n_tokens)
        if (starts_assignment(tokens, n_tokens, i)) exit
        select case (tokens(i)%kind)
        case (T_EQUALS)
          call fail_at(g, err, tokens(i)%line, 'misplaced ''='' in the values of '''//tokens(i_name)%text// &
                       ''' (each assignment is ''variable = value'')')
          return
        case (T_COMMA)
          if (expect_value) then
            call fail_at(g, err, tokens(i)%line, 'empty value in the list of '''//tokens(i_name)%text// &
                         ''' (a leading or doubled comma); give every value')
            return
          end if
          expect_value = .true.
        case default
          n_items = n_items + 1
          items(n_items) = i
          expect_value = .false.
        end select
        i = i + 1
      end do
      if (n_items == 0) then
        call fail_at(g, err, tokens(i_name)%line, ''''//tokens(i_name)%text//' ='' has no value')
        return
      end if
      call check_assignment(g, tokens, i_name, items(1:n_items), err)
      if (err%failed()) return
    end do
  end subroutine check_assignments

  pure logical function starts_assignment(tokens, n_tokens, i)
    type(token_t), intent(in) :: tokens(:)
    integer, intent(in) :: n_tokens, i
    starts_assignment = .false.
    if (i < n_tokens) starts_assignment = tokens(i)%kind == T_WORD .and. tokens(i + 1)%kind == T_EQUALS
  end function starts_assignment

  !> One assignment: known variable, subscript, number and type of the values, given once.
  subroutine check_assignment(g, tokens, i_name, items, err)
    type(group_input_t), intent(inout) :: g
    type(token_t), intent(in) :: tokens(:)
    integer, intent(in) :: i_name, items(:)
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: designator, base, subscript, value
    integer :: line, paren, s, lo, hi, colon, j, star, e, status, repeat
    integer(i8) :: n_values
    type(var_spec_t) :: spec
    character(len=len(g%specs%name)), allocatable :: names(:)

    designator = lower(tokens(i_name)%text)
    line = tokens(i_name)%line
    if (index(designator, '%') > 0) then
      call fail_at(g, err, line, ''''//designator//''': derived-type components (''%'') do not exist in a deck')
      return
    end if
    paren = index(designator, '(')
    if (paren == 0) then
      base = designator
    else
      base = designator(1:paren - 1)
    end if
    if (.not. is_identifier(base)) then
      call fail_at(g, err, line, ''''//designator//''' is not a variable name')
      return
    end if
    s = 0
    do j = 1, size(g%specs)
      if (trim(g%specs(j)%name) == base) s = j
    end do
    if (s == 0) then
      names = g%specs%name
      call fail_at(g, err, line, 'unknown variable '''//base//''''//suggestion(base, names, '')// &
                   ' (known: '//spec_list(g%specs)//')')
      return
    end if
    spec = g%specs(s)
    lo = 1
    hi = spec%n
    if (paren > 0) then
      if (spec%n == 1) then
        call fail_at(g, err, line, trim(spec%name)//' is a single value: no subscript ('''//designator//''')')
        return
      end if
      if (designator(len(designator):) /= ')') then
        call fail_at(g, err, line, 'bad subscript in '''//designator//'''')
        return
      end if
      subscript = designator(paren + 1:len(designator) - 1)
      colon = index(subscript, ':')
      if (colon == 0) then
        status = integer_literal_status(subscript)
        if (status == 0) read (subscript, *) lo
        hi = lo
      else
        status = max(integer_literal_status(subscript(1:colon - 1)), integer_literal_status(subscript(colon + 1:)))
        if (status == 0) then
          read (subscript(1:colon - 1), *) lo
          read (subscript(colon + 1:), *) hi
        end if
      end if
      if (status /= 0) then
        call fail_at(g, err, line, 'bad subscript in '''//designator//''' (use name(i) or name(i:j))')
        return
      end if
      if (lo < 1 .or. hi > spec%n .or. lo > hi) then
        call fail_at(g, err, line, 'subscript out of range in '''//designator//''': '//trim(spec%name)// &
                     ' has elements 1 to '//str(spec%n))
        return
      end if
    end if

    n_values = 0
    do j = 1, size(items)
      associate (tok => tokens(items(j)))
        star = 0
        if (tok%kind == T_WORD) star = index(tok%text, '*')
        if (star > 0) then
          if (integer_literal_status(tok%text(1:star - 1)) /= 0) then
            call fail_at(g, err, tok%line, 'bad repeat count in '''//tok%text//''' for '//trim(spec%name))
            return
          end if
          read (tok%text(1:star - 1), *) repeat
          value = tok%text(star + 1:)
          if (repeat < 1) then
            call fail_at(g, err, tok%line, 'bad repeat count in '''//tok%text//''' for '//trim(spec%name))
            return
          end if
          if (len(value) == 0) then
            call fail_at(g, err, tok%line, ''''//tok%text//''' without a value (an empty value) for '// &
                         trim(spec%name)//'; give every value')
            return
          end if
          n_values = n_values + repeat
          call check_value(g, spec, T_WORD, value, tok%line, err)
        else
          n_values = n_values + 1
          call check_value(g, spec, tok%kind, tok%text, tok%line, err)
        end if
        if (err%failed()) return
      end associate
    end do
    if (n_values /= hi - lo + 1) then
      if (hi == lo) then
        call fail_at(g, err, line, designator//' takes one value, got '//str(n_values))
      else
        call fail_at(g, err, line, designator//' takes '//str(hi - lo + 1)//' values, got '//str(n_values))
      end if
      return
    end if
    do e = lo, hi
      if (g%given_line(e, s) > 0) then
        call fail_at(g, err, line, trim(spec%name)//' is given twice (also on line '//str(g%given_line(e, s))//')')
        return
      end if
    end do
    g%given_line(lo:hi, s) = line
  end subroutine check_assignment

  !> The form of one value against the variable's type, before Fortran reads it.
  subroutine check_value(g, spec, token_kind, text, line, err)
    type(group_input_t), intent(in) :: g
    type(var_spec_t), intent(in) :: spec
    integer, intent(in) :: token_kind, line
    character(len=*), intent(in) :: text
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: name
    integer :: status
    name = trim(spec%name)
    select case (spec%kind)
    case (V_CHARACTER)
      if (token_kind /= T_STRING) then
        call fail_at(g, err, line, name//' needs quoted text, e.g. '//name//' = '''//text//'''')
      else if (len(text) > spec%length) then
        call fail_at(g, err, line, name//' is longer than '//str(spec%length)//' characters')
      end if
    case (V_REAL)
      if (token_kind == T_STRING) then
        call fail_at(g, err, line, name//' needs a number, got the text '''//text//'''')
        return
      end if
      status = real_literal_status(lower(text))
      if (status == 1) then
        call fail_at(g, err, line, name//' needs a number, got '''//text//'''')
      else if (status == 2) then
        call fail_at(g, err, line, name//' must be a finite number, got '''//text//''' (NaN or Inf)')
      else if (status == 3) then
        call fail_at(g, err, line, name//' = '//text//' is out of range (|value| < 1e308)')
      end if
    case (V_INTEGER)
      if (token_kind == T_STRING) then
        call fail_at(g, err, line, name//' needs a whole number, got the text '''//text//'''')
        return
      end if
      status = integer_literal_status(text)
      if (status == 1) then
        call fail_at(g, err, line, name//' needs a whole number, got '''//text//'''')
      else if (status == 3) then
        call fail_at(g, err, line, name//' = '//text//' is out of range for an integer')
      end if
    case (V_LOGICAL)
      if (token_kind == T_STRING .or. .not. is_logical_literal(lower(text))) then
        call fail_at(g, err, line, name//' needs .true. or .false., got '''//text//'''')
      end if
    end select
  end subroutine check_value

  !> 0: a real literal ([sign] digits [. digits] [e|d [sign] digits]); 1: not a number;
  !> 2: NaN or Inf; 3: |value| >= 1e308 (would overflow, and trap in the debug build).
  pure integer function real_literal_status(text) result(status)
    character(len=*), intent(in) :: text
    integer :: i, n, n_int, n_frac, first_nonzero, e10, n_exp_digits, exp_start
    integer(i8) :: exponent
    logical :: negative_exponent
    n = len(text)
    status = 1
    if (n == 0) return
    i = 1
    if (text(1:1) == '+' .or. text(1:1) == '-') i = 2
    if (text(i:) == 'nan' .or. text(i:) == 'inf' .or. text(i:) == 'infinity' .or. &
        (len(text(i:)) > 3 .and. text(i:min(n, i + 3)) == 'nan(')) then
      status = 2
      return
    end if
    n_int = 0
    first_nonzero = 0
    e10 = 0
    do while (i <= n)
      if (.not. is_digit(text(i:i))) exit
      n_int = n_int + 1
      if (first_nonzero == 0 .and. text(i:i) /= '0') first_nonzero = n_int
      i = i + 1
    end do
    n_frac = 0
    if (i <= n) then
      if (text(i:i) == '.') then
        i = i + 1
        do while (i <= n)
          if (.not. is_digit(text(i:i))) exit
          n_frac = n_frac + 1
          if (first_nonzero == 0 .and. text(i:i) /= '0') first_nonzero = -n_frac
          i = i + 1
        end do
      end if
    end if
    if (n_int + n_frac == 0) return
    exponent = 0
    if (i <= n) then
      if (index('ed', text(i:i)) == 0) return
      i = i + 1
      negative_exponent = .false.
      if (i <= n) then
        if (text(i:i) == '+' .or. text(i:i) == '-') then
          negative_exponent = text(i:i) == '-'
          i = i + 1
        end if
      end if
      exp_start = i
      n_exp_digits = 0
      do while (i <= n)
        if (.not. is_digit(text(i:i))) return
        n_exp_digits = n_exp_digits + 1
        i = i + 1
      end do
      if (n_exp_digits == 0) return
      if (n_exp_digits > 9) then
        exponent = 999999999_i8
      else
        exponent = 0
        do i = exp_start, n
          exponent = 10*exponent + (iachar(text(i:i)) - iachar('0'))
        end do
      end if
      if (negative_exponent) exponent = -exponent
    end if
    status = 0
    if (first_nonzero == 0) return   ! zero
    ! Decimal exponent of the leading digit: 123.4 -> 2, 0.0012 -> -3.
    if (first_nonzero > 0) then
      e10 = n_int - first_nonzero
    else
      e10 = first_nonzero
    end if
    if (e10 + exponent >= 308_i8) status = 3
  end function real_literal_status

  !> 0: an integer literal in the default integer range; 1: not an integer; 3: out of range.
  pure integer function integer_literal_status(text) result(status)
    character(len=*), intent(in) :: text
    integer :: i, first, n_significant
    integer(i8) :: value
    status = 1
    if (len(text) == 0) return
    first = 1
    if (text(1:1) == '+' .or. text(1:1) == '-') first = 2
    if (first > len(text)) return
    do i = first, len(text)
      if (.not. is_digit(text(i:i))) return
    end do
    n_significant = len(text) - first + 1 - (verify(text(first:), '0') - 1)
    if (verify(text(first:), '0') == 0) n_significant = 0
    status = 3
    if (n_significant > 12) return
    value = 0
    do i = first, len(text)
      value = 10*value + (iachar(text(i:i)) - iachar('0'))
    end do
    if (text(1:1) == '-') value = -value
    if (value > huge(0) .or. value < -huge(0) - 1_i8) return
    status = 0
  end function integer_literal_status

  pure logical function is_logical_literal(text)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: core
    integer :: a, b
    a = 1
    b = len(text)
    if (b >= 1) then
      if (text(1:1) == '.') a = 2
      if (text(b:b) == '.') b = b - 1
    end if
    core = ''
    if (b >= a) core = text(a:b)
    is_logical_literal = core == 't' .or. core == 'f' .or. core == 'true' .or. core == 'false'
  end function is_logical_literal

  elemental logical function is_digit(ch)
    character, intent(in) :: ch
    is_digit = ch >= '0' .and. ch <= '9'
  end function is_digit

  pure logical function is_identifier(text)
    character(len=*), intent(in) :: text
    integer :: i
    is_identifier = len(text) > 0
    if (.not. is_identifier) return
    is_identifier = text(1:1) >= 'a' .and. text(1:1) <= 'z'
    do i = 2, len(text)
      if (.not. is_name_char(text(i:i))) is_identifier = .false.
    end do
  end function is_identifier

  !> Translates a failed namelist READ (should the checks above have let something through).
  subroutine translate_read_error(g, ios, iomsg, err)
    type(group_input_t), intent(in) :: g
    integer, intent(in) :: ios
    character(len=*), intent(in) :: iomsg
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: msg, word
    msg = trim(iomsg)
    word = lower(last_word(msg))
    if (ios < 0) then
      call fail_at(g, err, g%line, 'the group ends before its closing ''/'' ('//msg//')')
    else if (index(msg, 'Cannot match namelist object name') > 0) then
      call fail_at(g, err, word_line(g, word), 'unknown variable or misplaced value '''//word//'''')
    else if (index(msg, 'Bad data for namelist object') > 0 .or. index(msg, 'Bad ') == 1) then
      call fail_at(g, err, word_line(g, word), 'wrong type of value for '''//word//''' ('//msg//')')
    else if (index(msg, 'Qualifier for a scalar') > 0) then
      call fail_at(g, err, word_line(g, word), word//' is a single value: no subscript')
    else if (index(msg, 'index triplet') > 0) then
      call fail_at(g, err, word_line(g, word), 'bad subscript for '''//word//'''')
    else if (index(msg, 'out of range for namelist variable') > 0) then
      call fail_at(g, err, word_line(g, word), 'subscript out of range for '''//word//'''')
    else if (index(msg, 'Equal sign must follow namelist object name') > 0) then
      call fail_at(g, err, word_line(g, word), 'expected ''='' after '''//word//'''')
    else
      call fail_at(g, err, g%line, 'cannot read the group: '//msg)
    end if
  end subroutine translate_read_error

  pure function last_word(text) result(word)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: word
    integer :: blank
    blank = index(trim(text), ' ', back=.true.)
    word = trim(text(blank + 1:))
  end function last_word

  !> Deck line where word first appears as a whole word in the group (the group's line if not).
  pure integer function word_line(g, word) result(line)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: word
    character(len=:), allocatable :: text
    integer :: r, p, from
    logical :: left_ok, right_ok
    line = g%line
    if (len(word) == 0) return
    do r = 1, size(g%text)
      text = lower(g%text(r))
      from = 1
      do
        p = index(text(from:), word)
        if (p == 0) exit
        p = p + from - 1
        left_ok = p == 1
        if (.not. left_ok) left_ok = .not. is_name_char(text(p - 1:p - 1))
        right_ok = p + len(word) > len(text)
        if (.not. right_ok) right_ok = .not. is_name_char(text(p + len(word):p + len(word)))
        if (left_ok .and. right_ok) then
          line = g%line + r - 1
          return
        end if
        from = p + 1
      end do
    end do
  end function word_line

  ! ---------------------------------------------------------------------------------------
  ! What the deck gives, and error messages
  ! ---------------------------------------------------------------------------------------

  pure integer function spec_index(g, name) result(s)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: name
    integer :: j
    s = 0
    do j = 1, size(g%specs)
      if (trim(g%specs(j)%name) == name) s = j
    end do
  end function spec_index

  !> Whether the deck gives the variable (any element of it).
  pure logical function given(g, name)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: name
    given = any(g%given_line(:, spec_index(g, name)) > 0)
  end function given

  pure logical function given_element(g, name, element)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: name
    integer, intent(in) :: element
    given_element = g%given_line(element, spec_index(g, name)) > 0
  end function given_element

  !> First line where any of the given elements of the variable is given (the group's
  !> first line if none is): a message about size(2) points at size(2), not at size(1).
  pure integer function first_element_line(g, name, elements) result(line)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: name
    integer, intent(in) :: elements(:)
    integer :: lines(size(elements))
    lines = g%given_line(elements, spec_index(g, name))
    line = g%line
    if (any(lines > 0)) line = minval(lines, mask=lines > 0)
  end function first_element_line

  !> Line where the variable is given (the group's first line if it is not).
  pure integer function var_line(g, name) result(line)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: name
    integer :: s
    s = spec_index(g, name)
    line = g%line
    if (s == 0) return
    if (any(g%given_line(:, s) > 0)) line = minval(g%given_line(:, s), mask=g%given_line(:, s) > 0)
  end function var_line

  !> Sets err: '<deck>:<line of name>: <group label>: message'.
  subroutine fail(g, err, name, message)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: name, message
    call fail_at(g, err, var_line(g, name), message)
  end subroutine fail

  subroutine fail_at(g, err, line, message)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    integer, intent(in) :: line
    character(len=*), intent(in) :: message
    call err%set(ERR_INPUT, g%deck_path//':'//str(line)//': '//g%label//': '//message)
  end subroutine fail_at

  !> Every real the deck gives must be finite (the literal check rejects NaN and Inf already;
  !> this guards what the READ produced).
  subroutine require_finite(g, err, name, values)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: name
    real(dp), intent(in) :: values(:)
    if (err%failed()) return
    if (.not. all(ieee_is_finite(values))) call fail(g, err, name, name//' must be a finite number (NaN or Inf)')
  end subroutine require_finite

  !> ' (did you mean ''x''?)' for the closest known name within two edits, else ''.
  pure function suggestion(word, known, prefix) result(text)
    character(len=*), intent(in) :: word, known(:), prefix
    character(len=:), allocatable :: text
    integer :: j, d, best, best_j
    best = huge(0)
    best_j = 0
    do j = 1, size(known)
      d = edit_distance(word, trim(known(j)))
      if (d < best) then
        best = d
        best_j = j
      end if
    end do
    text = ''
    if (best_j > 0 .and. best <= 2) text = ' (did you mean '''//prefix//trim(known(best_j))//'''?)'
  end function suggestion

  !> Levenshtein distance (insertions, deletions, substitutions).
  pure integer function edit_distance(a, b) result(d)
    character(len=*), intent(in) :: a, b
    integer :: previous(0:len(b)), current(0:len(b)), i, j
    previous = [(j, j=0, len(b))]
    do i = 1, len(a)
      current(0) = i
      do j = 1, len(b)
        current(j) = min(previous(j) + 1, current(j - 1) + 1, &
                         previous(j - 1) + merge(0, 1, a(i:i) == b(j:j)))
      end do
      previous = current
    end do
    d = previous(len(b))
  end function edit_distance

  pure function spec_list(specs) result(text)
    type(var_spec_t), intent(in) :: specs(:)
    character(len=:), allocatable :: text
    integer :: j
    text = trim(specs(1)%name)
    do j = 2, size(specs)
      text = text//', '//trim(specs(j)%name)
    end do
  end function spec_list

  ! ---------------------------------------------------------------------------------------
  ! The groups
  ! ---------------------------------------------------------------------------------------

  !> Opens, tokenizes and checks a group's assignments (label fixed beforehand).
  subroutine prepare_group(g, err)
    type(group_input_t), intent(inout) :: g
    type(error_t), intent(inout) :: err
    type(token_t), allocatable :: tokens(:)
    integer :: n_tokens
    call tokenize(g, tokens, n_tokens, err)
    if (err%failed()) return
    call check_assignments(g, tokens, n_tokens, err)
  end subroutine prepare_group

  subroutine read_run_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(run_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    character(len=len(config%title)) :: title
    real(dp) :: t_end, dt_max, gravity(3)
    integer :: ios
    character(len=512) :: msg
    namelist /run/ title, t_end, dt_max, gravity

    call open_group(src, group, run_vars, '&run', g)
    call prepare_group(g, err)
    if (err%failed()) return
    ! Defaults reset before the read: config is intent(out), so it holds the type's defaults.
    title = config%title
    t_end = config%t_end
    dt_max = config%dt_max
    gravity = config%gravity
    msg = ''
    read (g%text, nml=run, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%title = title
    config%t_end = t_end
    config%dt_max = dt_max
    config%gravity = gravity

    call require_finite(g, err, 't_end', [t_end])
    call require_finite(g, err, 'dt_max', [dt_max])
    call require_finite(g, err, 'gravity', gravity)
    if (err%failed()) return
    if (.not. given(g, 't_end')) then
      call fail(g, err, '', 't_end is required (end time of the run [s])')
    else if (t_end <= 0.0_dp) then
      call fail(g, err, 't_end', 't_end must be > 0 s, got '//real_text(t_end))
    else if (.not. given(g, 'dt_max')) then
      call fail(g, err, '', 'dt_max is required (largest time step [s])')
    else if (dt_max <= 0.0_dp) then
      call fail(g, err, 'dt_max', 'dt_max must be > 0 s, got '//real_text(dt_max))
    else if (dt_max > t_end) then
      call fail(g, err, 'dt_max', 'dt_max = '//real_text(dt_max)//' s must not exceed t_end = '// &
                real_text(t_end)//' s')
    end if
  end subroutine read_run_group

  subroutine read_integrator_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(integrator_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    real(dp) :: newmark_beta, newmark_gamma, rotation_tolerance
    integer :: rotation_max_iterations
    character(len=len(config%rotation)) :: rotation
    integer :: ios
    character(len=512) :: msg
    namelist /integrator/ newmark_beta, newmark_gamma, rotation_tolerance, rotation_max_iterations, rotation

    call open_group(src, group, integrator_vars, '&integrator', g)
    call prepare_group(g, err)
    if (err%failed()) return
    newmark_beta = config%newmark_beta
    newmark_gamma = config%newmark_gamma
    rotation_tolerance = config%rotation_tolerance
    rotation_max_iterations = config%rotation_max_iterations
    rotation = config%rotation
    msg = ''
    read (g%text, nml=integrator, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%newmark_beta = newmark_beta
    config%newmark_gamma = newmark_gamma
    config%rotation_tolerance = rotation_tolerance
    config%rotation_max_iterations = rotation_max_iterations
    config%rotation = lower(adjustl(rotation))

    call require_finite(g, err, 'newmark_beta', [newmark_beta])
    call require_finite(g, err, 'newmark_gamma', [newmark_gamma])
    call require_finite(g, err, 'rotation_tolerance', [rotation_tolerance])
    if (err%failed()) return
    ! Newmark is unconditionally stable for 2 beta >= gamma >= 1/2; gamma < 1/2 amplifies
    ! errors (unstable), gamma > 1/2 adds numerical damping (first order), beta > 1/2 is
    ! outside the family's useful range. beta < gamma/2 (e.g. beta = 0, explicit) is allowed:
    ! it is only conditionally stable, which free flight between contacts does not stress.
    if (newmark_beta < 0.0_dp .or. newmark_beta > 0.5_dp) then
      call fail(g, err, 'newmark_beta', 'newmark_beta must be in [0, 0.5], got '//real_text(newmark_beta)// &
                ' (unconditional stability needs 2 beta >= gamma >= 1/2)')
    else if (newmark_gamma < 0.5_dp .or. newmark_gamma > 1.0_dp) then
      call fail(g, err, 'newmark_gamma', 'newmark_gamma must be in [0.5, 1], got '//real_text(newmark_gamma)// &
                ' (gamma < 1/2 is unstable; gamma > 1/2 damps, 2 beta >= gamma >= 1/2 is unconditionally stable)')
    else if (rotation_tolerance <= 0.0_dp .or. rotation_tolerance >= 1.0_dp) then
      call fail(g, err, 'rotation_tolerance', 'rotation_tolerance must be in (0, 1) (a relative change), got '// &
                real_text(rotation_tolerance))
    else if (rotation_max_iterations < 1) then
      call fail(g, err, 'rotation_max_iterations', 'rotation_max_iterations must be >= 1, got '// &
                str(rotation_max_iterations))
    else if (config%rotation /= ROTATION_NEWMARK .and. config%rotation /= ROTATION_EXACT) then
      call fail(g, err, 'rotation', 'unknown rotation '''//trim(rotation)//''' (known: '''//ROTATION_NEWMARK// &
                ''', '''//ROTATION_EXACT//''')')
    end if
  end subroutine read_integrator_group

  subroutine read_contact_group(src, group, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    type(contact_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    real(dp) :: restitution, friction, min_separation, rest_speed, sleep_speed, sleep_time
    integer :: ios
    character(len=512) :: msg
    namelist /contact/ restitution, friction, min_separation, rest_speed, sleep_speed, sleep_time

    call open_group(src, group, contact_vars, '&contact', g)
    call prepare_group(g, err)
    if (err%failed()) return
    restitution = config%restitution
    friction = config%friction
    min_separation = config%min_separation
    rest_speed = config%rest_speed
    sleep_speed = config%sleep_speed
    sleep_time = config%sleep_time
    msg = ''
    read (g%text, nml=contact, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%restitution = restitution
    config%friction = friction
    config%min_separation = min_separation
    config%rest_speed = rest_speed
    config%sleep_speed = sleep_speed
    config%sleep_time = sleep_time

    call require_finite(g, err, 'restitution', [restitution])
    call require_finite(g, err, 'friction', [friction])
    call require_finite(g, err, 'min_separation', [min_separation])
    call require_finite(g, err, 'rest_speed', [rest_speed])
    call require_finite(g, err, 'sleep_speed', [sleep_speed])
    call require_finite(g, err, 'sleep_time', [sleep_time])
    if (err%failed()) return
    if (restitution < 0.0_dp .or. restitution > 1.0_dp) then
      call fail(g, err, 'restitution', 'restitution must be in [0, 1], got '//real_text(restitution))
    else if (friction < 0.0_dp) then
      call fail(g, err, 'friction', 'friction must be >= 0, got '//real_text(friction))
    else if (min_separation /= DECK_AUTO .and. min_separation <= 0.0_dp) then
      ! 0 would let the time of contact collapse to zero (DEVELOPERS.md, the method).
      call fail(g, err, 'min_separation', 'min_separation must be > 0 m, or -1 for auto, got '// &
                real_text(min_separation))
    else if (rest_speed /= DECK_AUTO .and. rest_speed < 0.0_dp) then
      call fail(g, err, 'rest_speed', 'rest_speed must be >= 0 m/s, or -1 for auto, got '//real_text(rest_speed))
    else if (sleep_speed /= DECK_AUTO .and. sleep_speed < 0.0_dp) then
      call fail(g, err, 'sleep_speed', 'sleep_speed must be >= 0 m/s (0: never sleep), or -1 for auto, got '// &
                real_text(sleep_speed))
    else if (sleep_time <= 0.0_dp) then
      call fail(g, err, 'sleep_time', 'sleep_time must be > 0 s, got '//real_text(sleep_time))
    end if
  end subroutine read_contact_group

  subroutine read_output_group(src, group, folder, config, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    character(len=*), intent(in) :: folder
    type(output_config_t), intent(out) :: config
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    character(len=len(config%dir)) :: dir
    real(dp) :: interval, checkpoint_interval, progress_interval, history_interval
    logical :: write_frames, check_overlaps
    character(len=:), allocatable :: resolved
    integer :: ios
    character(len=512) :: msg
    namelist /output/ dir, interval, checkpoint_interval, progress_interval, history_interval, write_frames, &
      check_overlaps

    call open_group(src, group, output_vars, '&output', g)
    call prepare_group(g, err)
    if (err%failed()) return
    dir = config%dir
    interval = config%interval
    checkpoint_interval = config%checkpoint_interval
    progress_interval = config%progress_interval
    history_interval = config%history_interval
    write_frames = config%write_frames
    check_overlaps = config%check_overlaps
    msg = ''
    read (g%text, nml=output, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    config%interval = interval
    config%checkpoint_interval = checkpoint_interval
    config%progress_interval = progress_interval
    config%history_interval = history_interval
    config%write_frames = write_frames
    config%check_overlaps = check_overlaps

    call require_finite(g, err, 'interval', [interval])
    call require_finite(g, err, 'history_interval', [history_interval])
    call require_finite(g, err, 'checkpoint_interval', [checkpoint_interval])
    call require_finite(g, err, 'progress_interval', [progress_interval])
    if (err%failed()) return
    if (len_trim(dir) == 0) then
      call fail(g, err, 'dir', 'dir must not be blank')
      return
    end if
    resolved = resolve_path(folder, dir)
    if (len(resolved) > len(config%dir)) then
      call fail(g, err, 'dir', 'dir resolved against the deck''s folder is longer than '// &
                str(len(config%dir))//' characters')
      return
    end if
    config%dir = resolved
    if (interval /= DECK_AUTO .and. interval <= 0.0_dp) then
      call fail(g, err, 'interval', 'interval must be > 0 s, or -1 for auto (t_end/100), got '// &
                real_text(interval))
    else if (checkpoint_interval < 0.0_dp) then
      call fail(g, err, 'checkpoint_interval', 'checkpoint_interval must be >= 0 s (0: only at the end), got '// &
                real_text(checkpoint_interval))
    else if (progress_interval <= 0.0_dp) then
      call fail(g, err, 'progress_interval', 'progress_interval must be > 0 s, got '//real_text(progress_interval))
    else if (history_interval /= DECK_AUTO .and. history_interval <= 0.0_dp) then
      call fail(g, err, 'history_interval', 'history_interval must be > 0 s, or -1 for auto (interval/10), got '// &
                real_text(history_interval))
    end if
  end subroutine read_output_group

  !> One &body: defaults reset (spec is intent(out)), read, then checked for its shape.
  subroutine read_body_group(src, group, index, folder, spec, err)
    type(source_t), intent(in) :: src
    type(group_t), intent(in) :: group
    integer, intent(in) :: index
    character(len=*), intent(in) :: folder
    type(body_spec_t), intent(out) :: spec
    type(error_t), intent(inout) :: err
    type(group_input_t) :: g
    type(token_t), allocatable :: tokens(:)
    integer :: n_tokens, i
    character(len=:), allocatable :: label_name

    call open_group(src, group, body_vars, '&body #'//str(index), g)
    call tokenize(g, tokens, n_tokens, err)
    if (err%failed()) return
    ! The name goes into every message, so find it before checking anything else.
    label_name = 'body'//str(index)
    do i = 1, n_tokens - 2
      if (tokens(i)%kind == T_WORD .and. tokens(i + 1)%kind == T_EQUALS .and. tokens(i + 2)%kind == T_STRING) then
        if (lower(tokens(i)%text) == 'name') label_name = trim(tokens(i + 2)%text)
      end if
    end do
    g%label = '&body #'//str(index)//' '''//label_name//''''
    call check_assignments(g, tokens, n_tokens, err)
    if (err%failed()) return
    call namelist_read_body(g, spec, err)
    if (err%failed()) return
    spec%line = group%first_line
    if (.not. given(g, 'name')) spec%name = 'body'//str(index)
    call check_body(g, folder, spec, err)
  end subroutine read_body_group

  !> The namelist READ of one &body into spec (which holds the defaults on entry).
  subroutine namelist_read_body(g, spec, err)
    type(group_input_t), intent(in) :: g
    type(body_spec_t), intent(inout) :: spec
    type(error_t), intent(inout) :: err
    character(len=len(spec%name)) :: name
    character(len=len(spec%shape)) :: shape
    character(len=len(spec%mesh_file)) :: mesh_file
    real(dp) :: radius, size(3), minor_radius, thickness, scale, density, mass, position(3), orientation(4), &
                velocity(3), angular_velocity(3), spacing(3), jitter_position, jitter_angle, jitter_velocity, &
                inertia(3), restitution, friction
    integer :: segments, tube_segments, copies(3), seed
    logical :: fixed
    integer :: ios
    character(len=512) :: msg
    namelist /body/ name, shape, radius, size, segments, minor_radius, tube_segments, thickness, mesh_file, &
      scale, density, mass, position, orientation, velocity, angular_velocity, fixed, copies, spacing, seed, &
      jitter_position, jitter_angle, jitter_velocity, inertia, restitution, friction

    name = spec%name
    shape = spec%shape
    radius = spec%radius
    size = spec%size
    segments = spec%segments
    minor_radius = spec%minor_radius
    tube_segments = spec%tube_segments
    thickness = spec%thickness
    mesh_file = spec%mesh_file
    scale = spec%scale
    density = spec%density
    mass = spec%mass
    position = spec%position
    orientation = spec%orientation
    velocity = spec%velocity
    angular_velocity = spec%angular_velocity
    fixed = spec%fixed
    copies = spec%copies
    spacing = spec%spacing
    seed = spec%seed
    jitter_position = spec%jitter_position
    jitter_angle = spec%jitter_angle
    jitter_velocity = spec%jitter_velocity
    inertia = spec%inertia
    restitution = spec%restitution
    friction = spec%friction
    msg = ''
    read (g%text, nml=body, iostat=ios, iomsg=msg)
    if (ios /= 0) then
      call translate_read_error(g, ios, msg, err)
      return
    end if
    spec%name = name
    spec%shape = lower(adjustl(shape))
    spec%radius = radius
    spec%size = size
    spec%segments = segments
    spec%minor_radius = minor_radius
    spec%tube_segments = tube_segments
    spec%thickness = thickness
    spec%mesh_file = mesh_file
    spec%scale = scale
    spec%density = density
    spec%mass = mass
    spec%position = position
    spec%orientation = orientation
    spec%velocity = velocity
    spec%angular_velocity = angular_velocity
    spec%fixed = fixed
    spec%copies = copies
    spec%spacing = spacing
    spec%seed = seed
    spec%jitter_position = jitter_position
    spec%jitter_angle = jitter_angle
    spec%jitter_velocity = jitter_velocity
    spec%inertia = inertia
    spec%restitution = restitution
    spec%friction = friction
  end subroutine namelist_read_body

  !> inertia: auto (all -1) or three positive moments that a rigid body can have (each at
  !> most the sum of the other two), for a body with mass, not a fixed one.
  subroutine check_inertia(g, spec, err)
    type(group_input_t), intent(in) :: g
    type(body_spec_t), intent(in) :: spec
    type(error_t), intent(inout) :: err
    real(dp) :: moments(3)
    integer :: k
    moments = spec%inertia
    if (all(moments == DECK_AUTO)) return
    if (any(moments <= 0.0_dp)) then
      call fail(g, err, 'inertia', 'inertia needs three moments > 0 kg m^2 (or none, for the solid''s own)')
    else if (spec%fixed) then
      call fail(g, err, 'inertia', 'a fixed body never moves: inertia must not be given')
    else
      do k = 1, 3
        ! Each moment is sum of m (y^2 + z^2)-like terms: I_k <= I_i + I_j for any body
        ! (equality for a flat plate); round-off slack of 1e-12 relative.
        if (moments(k) > (sum(moments) - moments(k))*(1.0_dp + 1.0e-12_dp)) then
          call fail(g, err, 'inertia', 'inertia: no rigid body has a moment larger than the sum of the other two')
          return
        end if
      end do
    end if
  end subroutine check_inertia

  !> The rules of a &body (docs/input.md): shape and its variables, mass, orientation,
  !> motion of fixed bodies, lattice and jitter.
  subroutine check_body(g, folder, spec, err)
    type(group_input_t), intent(in) :: g
    character(len=*), intent(in) :: folder
    type(body_spec_t), intent(inout) :: spec
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: resolved, shape
    real(dp) :: norm
    integer :: axis
    logical :: exists
    character, parameter :: axis_name(3) = ['x', 'y', 'z']

    call require_finite(g, err, 'radius', [spec%radius])
    call require_finite(g, err, 'size', spec%size)
    call require_finite(g, err, 'minor_radius', [spec%minor_radius])
    call require_finite(g, err, 'thickness', [spec%thickness])
    call require_finite(g, err, 'scale', [spec%scale])
    call require_finite(g, err, 'density', [spec%density])
    call require_finite(g, err, 'mass', [spec%mass])
    call require_finite(g, err, 'position', spec%position)
    call require_finite(g, err, 'orientation', spec%orientation)
    call require_finite(g, err, 'velocity', spec%velocity)
    call require_finite(g, err, 'angular_velocity', spec%angular_velocity)
    call require_finite(g, err, 'spacing', spec%spacing)
    call require_finite(g, err, 'jitter_position', [spec%jitter_position])
    call require_finite(g, err, 'jitter_angle', [spec%jitter_angle])
    call require_finite(g, err, 'jitter_velocity', [spec%jitter_velocity])
    call require_finite(g, err, 'inertia', spec%inertia)
    call require_finite(g, err, 'restitution', [spec%restitution])
    call require_finite(g, err, 'friction', [spec%friction])
    if (err%failed()) return
    call check_inertia(g, spec, err)
    if (err%failed()) return

    if (len_trim(spec%name) == 0) then
      call fail(g, err, 'name', 'name must not be blank')
      return
    end if

    ! Shape and the variables that belong to it; a variable of another shape is an error
    ! (a box given a radius is a mistake, not a remark).
    if (.not. given(g, 'shape')) then
      call fail(g, err, '', 'shape is required (one of '//known_shapes//')')
      return
    end if
    if (findloc(shape_names, trim(spec%shape), dim=1) == 0) then
      call fail(g, err, 'shape', 'unknown shape '''//trim(spec%shape)//''''// &
                suggestion(trim(spec%shape), shape_names, '')//' (known: '//known_shapes//')')
      return
    end if
    shape = trim(spec%shape)
    call reject_unless(g, err, 'radius', shape == 'sphere' .or. shape == 'cylinder' .or. shape == 'torus', shape)
    call reject_unless(g, err, 'segments', shape == 'cylinder' .or. shape == 'torus', shape)
    call reject_unless(g, err, 'mesh_file', shape == 'mesh', shape)
    call reject_unless(g, err, 'scale', shape == 'mesh', shape)
    call reject_unless(g, err, 'size', shape == 'box' .or. shape == 'cylinder' .or. shape == 'tetrahedron' .or. &
                       shape == 'l_prism', shape)
    call reject_unless(g, err, 'minor_radius', shape == 'torus', shape)
    call reject_unless(g, err, 'tube_segments', shape == 'torus', shape)
    call reject_unless(g, err, 'thickness', shape == 'l_prism', shape)
    if (err%failed()) return
    select case (shape)
    case ('sphere')
      call require_positive(g, err, 'radius', spec%radius, 'm', 'a sphere needs radius [m]')
    case ('box')
      call require_sizes(g, err, spec%size, 'a box needs all three edge lengths: size = x, y, z [m]')
    case ('cylinder')
      ! A cylinder's axis is its z axis: radius and length size(3) (size(1:2) are the box's).
      call require_positive(g, err, 'radius', spec%radius, 'm', 'a cylinder needs radius [m]')
      if (err%failed()) return
      if (given_element(g, 'size', 1) .or. given_element(g, 'size', 2)) then
        call fail_at(g, err, first_element_line(g, 'size', [1, 2]), 'a cylinder takes its length as '// &
                     'size(3) = L [m]; size(1) and size(2) do not apply (give radius)')
      else if (.not. given_element(g, 'size', 3)) then
        call fail(g, err, '', 'a cylinder needs its length: size(3) = L [m]')
      else if (spec%size(3) <= 0.0_dp) then
        call fail(g, err, 'size', 'size(3) (the cylinder''s length) must be > 0 m, got '//real_text(spec%size(3)))
      else if (spec%segments < 3) then
        call fail(g, err, 'segments', 'segments must be >= 3, got '//str(spec%segments))
      end if
    case ('tetrahedron')
      ! Regular: one length says it all, so size(2:3) given would be a mistake, not a remark.
      if (given_element(g, 'size', 2) .or. given_element(g, 'size', 3)) then
        call fail_at(g, err, first_element_line(g, 'size', [2, 3]), 'a tetrahedron takes its edge length as '// &
                     'size(1) = a [m]; size(2) and size(3) do not apply (it is regular)')
      else if (.not. given_element(g, 'size', 1)) then
        call fail(g, err, '', 'a tetrahedron needs its edge length: size(1) = a [m]')
      else if (spec%size(1) <= 0.0_dp) then
        call fail(g, err, 'size', 'size(1) (the tetrahedron''s edge length) must be > 0 m, got '// &
                  real_text(spec%size(1)))
      end if
    case ('torus')
      call require_positive(g, err, 'radius', spec%radius, 'm', &
                            'a torus needs radius [m], the radius of the circle through its tube''s centre')
      call require_positive(g, err, 'minor_radius', spec%minor_radius, 'm', &
                            'a torus needs minor_radius [m], the radius of its tube')
      if (err%failed()) return
      if (spec%minor_radius >= spec%radius) then
        ! r >= R: the tube reaches the axis and the surface would cross itself there.
        call fail(g, err, 'minor_radius', 'minor_radius = '//real_text(spec%minor_radius)// &
                  ' m must be < radius = '//real_text(spec%radius)//' m (the tube would reach the axis)')
      else if (spec%segments < 3) then
        call fail(g, err, 'segments', 'segments must be >= 3, got '//str(spec%segments))
      else if (spec%tube_segments < 3) then
        call fail(g, err, 'tube_segments', 'tube_segments must be >= 3, got '//str(spec%tube_segments))
      else if (2*int(spec%segments, i8)*int(spec%tube_segments, i8) > int(huge(0), i8)) then
        ! The mesh has 2 segments tube_segments faces, counted in default integers.
        call fail(g, err, 'tube_segments', 'segments x tube_segments = '//str(spec%segments)//' x '// &
                  str(spec%tube_segments)//' makes more than '//str(huge(0))//' faces')
      end if
    case ('l_prism')
      call require_sizes(g, err, spec%size, 'an l_prism needs all three lengths: size = x, y, z [m], '// &
                         'the outer edges of the L and its extrusion along z')
      call require_positive(g, err, 'thickness', spec%thickness, 'm', &
                            'an l_prism needs thickness [m], the width of its arms')
      if (err%failed()) return
      if (spec%thickness >= min(spec%size(1), spec%size(2))) then
        call fail(g, err, 'thickness', 'thickness = '//real_text(spec%thickness)// &
                  ' m must be < min(size(1), size(2)) = '//real_text(min(spec%size(1), spec%size(2)))// &
                  ' m (arms that wide fill the rectangle: use a box)')
      end if
    case ('mesh')
      if (.not. given(g, 'mesh_file') .or. len_trim(spec%mesh_file) == 0) then
        call fail(g, err, 'mesh_file', 'a mesh needs mesh_file = ''file''')
        return
      end if
      if (spec%scale <= 0.0_dp) then
        call fail(g, err, 'scale', 'scale must be > 0, got '//real_text(spec%scale))
        return
      end if
      resolved = resolve_path(folder, spec%mesh_file)
      inquire (file=resolved, exist=exists)
      if (.not. exists) then
        call fail(g, err, 'mesh_file', 'mesh_file '''//trim(spec%mesh_file)//''' not found (looked for '// &
                  resolved//')')
      else if (len(resolved) > len(spec%mesh_file)) then
        call fail(g, err, 'mesh_file', 'mesh_file resolved is longer than '//str(len(spec%mesh_file))//' characters')
      else
        spec%mesh_file = resolved
      end if
    end select
    if (err%failed()) return

    ! Mass: exactly one of density and mass (a fixed body needs neither: its mass is infinite).
    if (given(g, 'density') .and. given(g, 'mass')) then
      call fail_at(g, err, max(var_line(g, 'density'), var_line(g, 'mass')), &
                   'give density or mass, not both (density on line '//str(var_line(g, 'density'))// &
                   ', mass on line '//str(var_line(g, 'mass'))//')')
      return
    end if
    if (given(g, 'density')) then
      call require_positive(g, err, 'density', spec%density, 'kg/m^3', '')
    else if (given(g, 'mass')) then
      call require_positive(g, err, 'mass', spec%mass, 'kg', '')
    else if (.not. spec%fixed) then
      call fail(g, err, '', 'give density [kg/m^3] or mass [kg] (only a fixed body needs neither)')
    end if
    if (err%failed()) return

    ! Material: -1 (DECK_AUTO) takes the &contact value when the run is set up.
    if (spec%restitution /= DECK_AUTO .and. (spec%restitution < 0.0_dp .or. spec%restitution > 1.0_dp)) then
      call fail(g, err, 'restitution', 'restitution must be in [0, 1], or -1 for the &contact value, got '// &
                real_text(spec%restitution))
    else if (spec%friction /= DECK_AUTO .and. spec%friction < 0.0_dp) then
      call fail(g, err, 'friction', 'friction must be >= 0, or -1 for the &contact value, got '// &
                real_text(spec%friction))
    end if
    if (err%failed()) return

    ! Orientation: unit within the tolerance, then renormalised. A norm already within a few
    ! ulps of 1 is left alone, so that reading an effective deck back changes no bit.
    norm = norm2(spec%orientation)
    if (abs(norm - 1.0_dp) > unit_quaternion_tolerance) then
      call fail(g, err, 'orientation', 'orientation must be a unit quaternion (w, x, y, z): its norm is '// &
                real_text(norm)//', more than '//real_text(unit_quaternion_tolerance)//' from 1')
      return
    end if
    if (abs(norm - 1.0_dp) > 4.0_dp*epsilon(1.0_dp)) spec%orientation = spec%orientation/norm

    if (spec%fixed) then
      if (any(spec%velocity /= 0.0_dp)) then
        call fail(g, err, 'velocity', 'a fixed body never moves: velocity must be 0')
      else if (any(spec%angular_velocity /= 0.0_dp)) then
        call fail(g, err, 'angular_velocity', 'a fixed body never moves: angular_velocity must be 0')
      else if (spec%jitter_velocity /= 0.0_dp) then
        call fail(g, err, 'jitter_velocity', 'a fixed body never moves: jitter_velocity must be 0')
      end if
      if (err%failed()) return
    end if

    ! Lattice of copies.
    do axis = 1, 3
      if (spec%copies(axis) < 1) then
        call fail(g, err, 'copies', 'copies('//str(axis)//') must be >= 1, got '//str(spec%copies(axis)))
      else if (spec%spacing(axis) < 0.0_dp) then
        call fail(g, err, 'spacing', 'spacing('//str(axis)//') must be >= 0 m, got '//real_text(spec%spacing(axis)))
      else if (spec%copies(axis) > 1 .and. spec%spacing(axis) <= 0.0_dp) then
        call fail(g, err, 'copies', str(spec%copies(axis))//' copies along '//axis_name(axis)// &
                  ' need spacing('//str(axis)//') > 0 m')
      end if
      if (err%failed()) return
    end do
    if (product(int(spec%copies, i8)) > int(huge(0), i8)) then
      call fail(g, err, 'copies', 'copies = '//str(spec%copies(1))//', '//str(spec%copies(2))//', '// &
                str(spec%copies(3))//' makes more than '//str(huge(0))//' bodies')
      return
    end if

    ! Jitter.
    if (spec%jitter_position < 0.0_dp) then
      call fail(g, err, 'jitter_position', 'jitter_position must be >= 0 m, got '//real_text(spec%jitter_position))
    else if (spec%jitter_angle < 0.0_dp .or. spec%jitter_angle > pi) then
      call fail(g, err, 'jitter_angle', 'jitter_angle must be in [0, pi] rad, got '//real_text(spec%jitter_angle))
    else if (spec%jitter_velocity < 0.0_dp) then
      call fail(g, err, 'jitter_velocity', 'jitter_velocity must be >= 0 m/s, got '//real_text(spec%jitter_velocity))
    else if (spec%seed < 0) then
      call fail(g, err, 'seed', 'seed must be >= 0 (0: no jitter), got '//str(spec%seed))
    else if (spec%seed == 0 .and. (spec%jitter_position > 0.0_dp .or. spec%jitter_angle > 0.0_dp .or. &
                                   spec%jitter_velocity > 0.0_dp)) then
      call fail(g, err, 'seed', 'jitter needs a stated seed >= 1 (seed = 0 means no jitter)')
    end if
  end subroutine check_body

  !> Error if the variable is given although the shape does not use it.
  subroutine reject_unless(g, err, name, applies, shape)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: name, shape
    logical, intent(in) :: applies
    if (err%failed() .or. applies) return
    if (given(g, name)) call fail(g, err, name, name//' does not apply to shape '''//trim(shape)//''' ('// &
                                  shape_takes(shape)//')')
  end subroutine reject_unless

  !> What a shape is given, for messages.
  pure function shape_takes(shape) result(text)
    character(len=*), intent(in) :: shape
    character(len=:), allocatable :: text
    select case (trim(shape))
    case ('sphere')
      text = 'a sphere takes radius'
    case ('box')
      text = 'a box takes size = x, y, z'
    case ('cylinder')
      text = 'a cylinder takes radius, size(3) and segments'
    case ('tetrahedron')
      text = 'a tetrahedron takes size(1), its edge length'
    case ('torus')
      text = 'a torus takes radius, minor_radius, segments and tube_segments'
    case ('l_prism')
      text = 'an l_prism takes size = x, y, z and thickness'
    case ('mesh')
      text = 'a mesh takes mesh_file and scale'
    case default
      text = 'known shapes: '//known_shapes
    end select
  end function shape_takes

  !> All three elements of size given and > 0 (box, l_prism); missing says what is needed.
  subroutine require_sizes(g, err, size, missing)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    real(dp), intent(in) :: size(3)
    character(len=*), intent(in) :: missing
    integer :: axis
    do axis = 1, 3
      if (err%failed()) return
      if (.not. given_element(g, 'size', axis)) then
        call fail(g, err, 'size', missing//' (size('//str(axis)//') is missing)')
      else if (size(axis) <= 0.0_dp) then
        call fail(g, err, 'size', 'size('//str(axis)//') must be > 0 m, got '//real_text(size(axis)))
      end if
    end do
  end subroutine require_sizes

  subroutine require_positive(g, err, name, value, unit, missing)
    type(group_input_t), intent(in) :: g
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: name, unit, missing
    real(dp), intent(in) :: value
    if (err%failed()) return
    if (.not. given(g, name)) then
      call fail(g, err, '', missing)
    else if (value <= 0.0_dp) then
      call fail(g, err, name, name//' must be > 0 '//unit//', got '//real_text(value))
    end if
  end subroutine require_positive

  !> Checks across bodies: distinct names, a total count that fits an integer. Names are
  !> compared after sorting (n log n: decks written by tools may hold many &body groups).
  subroutine check_bodies_together(src, deck, err)
    type(source_t), intent(in) :: src
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
        call err%set(ERR_INPUT, src%path//':'//str(deck%bodies(second)%line)//': &body #'//str(second)//' '''// &
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
      call err%set(ERR_INPUT, src%path//': the deck describes '//str(total)//' bodies, more than '//str(huge(0)))
    end if
  end subroutine check_bodies_together

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

  ! ---------------------------------------------------------------------------------------
  ! Paths
  ! ---------------------------------------------------------------------------------------

  !> path resolved against folder (unless absolute), as an absolute path.
  function resolve_path(folder, path) result(resolved)
    character(len=*), intent(in) :: folder, path
    character(len=:), allocatable :: resolved
    if (is_absolute_path(adjustl(path))) then
      resolved = normalise_path(trim(adjustl(path)))
    else
      resolved = absolute_path(trim(folder)//'/'//trim(adjustl(path)))
    end if
  end function resolve_path

  !> The absolute form of path (the current folder prepended to a relative path).
  function absolute_path(path) result(absolute)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: absolute
    if (is_absolute_path(path)) then
      absolute = normalise_path(path)
    else
      absolute = normalise_path(current_folder()//'/'//path)
    end if
  end function absolute_path

  !> The current working folder (POSIX getcwd); '.' if it cannot be found.
  function current_folder() result(folder)
    character(len=:), allocatable :: folder
    interface
      function c_getcwd(buffer, size) bind(c, name='getcwd') result(p)
        import :: c_char, c_size_t, c_ptr
        character(kind=c_char), intent(out) :: buffer(*)
        integer(c_size_t), value :: size
        type(c_ptr) :: p
      end function c_getcwd
    end interface
    character(kind=c_char) :: buffer(4096)
    integer :: n
    if (.not. c_associated(c_getcwd(buffer, int(4096, c_size_t)))) then
      folder = '.'
      return
    end if
    n = 0
    do while (n < 4096)
      if (buffer(n + 1) == c_null_char) exit
      n = n + 1
    end do
    allocate (character(len=n) :: folder)
    do n = 1, len(folder)
      folder(n:n) = buffer(n)
    end do
  end function current_folder

  !> Drops empty and '.' segments ('a//./b/' -> 'a/b'); '..' is kept (symbolic links).
  pure function normalise_path(path) result(clean)
    character(len=*), intent(in) :: path
    character(len=:), allocatable :: clean, segment
    integer :: start, slash
    logical :: absolute
    absolute = is_absolute_path(path)
    clean = ''
    start = 1
    do while (start <= len(path))
      slash = index(path(start:), '/')
      if (slash == 0) then
        segment = path(start:)
        start = len(path) + 1
      else
        segment = path(start:start + slash - 2)
        start = start + slash
      end if
      if (len(segment) == 0 .or. segment == '.') cycle
      if (len(clean) == 0) then
        clean = segment
      else
        clean = clean//'/'//segment
      end if
    end do
    if (absolute) clean = '/'//clean
    if (len(clean) == 0) clean = '.'
  end function normalise_path

  ! ---------------------------------------------------------------------------------------
  ! Text helpers
  ! ---------------------------------------------------------------------------------------

  pure function unquote(text, quote) result(plain)
    character(len=*), intent(in) :: text
    character, intent(in) :: quote
    character(len=:), allocatable :: plain
    character(len=len(text)) :: buffer
    integer :: c, n
    n = 0
    c = 1
    do while (c <= len(text))
      n = n + 1
      buffer(n:n) = text(c:c)
      if (text(c:c) == quote) c = c + 1   ! a doubled quote is one quote
      c = c + 1
    end do
    plain = buffer(1:n)
  end function unquote

  pure function without_blanks(text) result(packed)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: packed
    character(len=len(text)) :: buffer
    integer :: c, n
    n = 0
    do c = 1, len(text)
      if (text(c:c) /= ' ') then
        n = n + 1
        buffer(n:n) = text(c:c)
      end if
    end do
    packed = buffer(1:n)
  end function without_blanks

  !> Shortest decimal text that reads back as exactly x ('0.25', '9.81', '1.0e-14').
  function real_text(x) result(text)
    real(dp), intent(in) :: x
    character(len=:), allocatable :: text
    character(len=48) :: buffer
    character(len=24) :: fmt
    character(len=:), allocatable :: digits, mantissa
    real(dp) :: back
    integer :: n_digits, ios, e_pos, exponent, first
    logical :: negative

    if (.not. ieee_is_finite(x)) then
      write (buffer, '(g0)') x
      text = trim(adjustl(buffer))
      return
    end if
    if (x == 0.0_dp) then
      text = merge('-0.0', ' 0.0', sign(1.0_dp, x) < 0.0_dp)
      text = trim(adjustl(text))
      return
    end if
    ! Near the top of the range fewer digits could round up past huge() and overflow.
    first = 1
    if (abs(x) > 1.0e307_dp) first = 17
    do n_digits = first, 17
      write (fmt, '(a,i0,a)') '(es48.', n_digits - 1, 'e4)'
      write (buffer, fmt) x
      read (buffer, *, iostat=ios) back
      if (ios == 0 .and. back == x) exit
    end do
    buffer = adjustl(buffer)
    negative = buffer(1:1) == '-'
    if (negative .or. buffer(1:1) == '+') buffer = buffer(2:)
    e_pos = scan(buffer, 'Ee')
    mantissa = buffer(1:e_pos - 1)
    read (buffer(e_pos + 1:), *) exponent
    digits = without_dot(mantissa)
    do while (len(digits) > 1 .and. digits(len(digits):) == '0')
      digits = digits(1:len(digits) - 1)
    end do
    if (exponent >= 0 .and. exponent <= 7) then
      if (len(digits) <= exponent + 1) then
        text = digits//repeat('0', exponent + 1 - len(digits))//'.0'
      else
        text = digits(1:exponent + 1)//'.'//digits(exponent + 2:)
      end if
    else if (exponent < 0 .and. exponent >= -4) then
      text = '0.'//repeat('0', -exponent - 1)//digits
    else if (len(digits) == 1) then
      text = digits//'.0e'//str(exponent)
    else
      text = digits(1:1)//'.'//digits(2:)//'e'//str(exponent)
    end if
    if (negative) text = '-'//text
  end function real_text

  pure function without_dot(text) result(packed)
    character(len=*), intent(in) :: text
    character(len=:), allocatable :: packed
    integer :: c
    packed = ''
    do c = 1, len(text)
      if (text(c:c) /= '.') packed = packed//text(c:c)
    end do
  end function without_dot

  ! ---------------------------------------------------------------------------------------
  ! The effective deck
  ! ---------------------------------------------------------------------------------------

  !> Writes deck as a namelist deck with every variable, defaults filled in, that read_deck
  !> reads back to the same deck_t (apart from path, folder and body lines). Values that are
  !> "auto" are written as -1 (DECK_AUTO); variables that do not apply (a box's radius, the
  !> mass of a body given by density) are written as comments. Reals are written with the
  !> fewest digits that read back exactly; paths are absolute.
  subroutine write_effective_deck(deck, unit)
    type(deck_t), intent(in) :: deck
    integer, intent(in) :: unit
    integer :: k
    character(len=:), allocatable :: shape, note

    write (unit, '(a)') '! ricochet effective input: every variable, defaults filled in (docs/input.md)'
    if (allocated(deck%path)) write (unit, '(a)') '! deck: '//deck%path
    write (unit, '(a)') '&run'
    call put_text(unit, 'title', deck%run%title)
    call put_real(unit, 't_end', [deck%run%t_end], '[s]')
    call put_real(unit, 'dt_max', [deck%run%dt_max], '[s]')
    call put_real(unit, 'gravity', deck%run%gravity, '[m/s^2]')
    write (unit, '(a)') '/'
    write (unit, '(a)') '&integrator'
    call put_real(unit, 'newmark_beta', [deck%integrator%newmark_beta], '')
    call put_real(unit, 'newmark_gamma', [deck%integrator%newmark_gamma], '')
    call put_real(unit, 'rotation_tolerance', [deck%integrator%rotation_tolerance], '[-] relative')
    call put_integer(unit, 'rotation_max_iterations', [deck%integrator%rotation_max_iterations], '')
    call put_text(unit, 'rotation', deck%integrator%rotation)
    write (unit, '(a)') '/'
    write (unit, '(a)') '&contact'
    call put_real(unit, 'restitution', [deck%contact%restitution], '')
    call put_real(unit, 'friction', [deck%contact%friction], '')
    note = '[m]'
    if (deck%contact%min_separation == DECK_AUTO) note = '[m] -1: auto, 1e-4 of the smallest body size'
    call put_real(unit, 'min_separation', [deck%contact%min_separation], note)
    note = '[m/s] below it impacts are inelastic'
    if (deck%contact%rest_speed == DECK_AUTO) note = '[m/s] -1: auto, max(2 |g| dt_max, sqrt(2 |g| min_separation))'
    call put_real(unit, 'rest_speed', [deck%contact%rest_speed], note)
    note = '[m/s] 0: never sleep'
    if (deck%contact%sleep_speed == DECK_AUTO) note = '[m/s] -1: auto, rest_speed/100'
    call put_real(unit, 'sleep_speed', [deck%contact%sleep_speed], note)
    call put_real(unit, 'sleep_time', [deck%contact%sleep_time], '[s]')
    write (unit, '(a)') '/'
    write (unit, '(a)') '&output'
    call put_text(unit, 'dir', deck%output%dir)
    note = '[s]'
    if (deck%output%interval == DECK_AUTO) note = '[s] -1: auto, t_end/100'
    call put_real(unit, 'interval', [deck%output%interval], note)
    call put_real(unit, 'checkpoint_interval', [deck%output%checkpoint_interval], '[s] 0: only at the end')
    call put_real(unit, 'progress_interval', [deck%output%progress_interval], '[s of wall time]')
    note = '[s]'
    if (deck%output%history_interval == DECK_AUTO) note = '[s] -1: auto, interval/10'
    call put_real(unit, 'history_interval', [deck%output%history_interval], note)
    call put_logical(unit, 'write_frames', deck%output%write_frames)
    call put_logical(unit, 'check_overlaps', deck%output%check_overlaps)
    write (unit, '(a)') '/'
    if (.not. allocated(deck%bodies)) return
    do k = 1, deck%n_bodies
      associate (b => deck%bodies(k))
        shape = trim(b%shape)
        write (unit, '(a)') '&body ! #'//str(k)
        call put_text(unit, 'name', b%name)
        call put_text(unit, 'shape', b%shape)
        select case (shape)
        case ('sphere', 'cylinder')
          call put_real(unit, 'radius', [b%radius], '[m]')
        case ('torus')
          call put_real(unit, 'radius', [b%radius], '[m] major radius, of the tube''s centre circle')
        case default
          call put_note(unit, 'radius: not used by shape '''//shape//'''')
        end select
        select case (shape)
        case ('box')
          call put_real(unit, 'size', b%size, '[m]')
        case ('l_prism')
          call put_real(unit, 'size', b%size, '[m] outer x, y, extrusion z')
        case ('cylinder')
          call put_real(unit, 'size(3)', [b%size(3)], '[m] length')
        case ('tetrahedron')
          call put_real(unit, 'size(1)', [b%size(1)], '[m] edge length')
        case default
          call put_note(unit, 'size: not used by shape '''//shape//'''')
        end select
        if (shape == 'cylinder' .or. shape == 'torus') then
          call put_integer(unit, 'segments', [b%segments], '')
        else
          call put_note(unit, 'segments: not used by shape '''//shape//'''')
        end if
        if (shape == 'torus') then
          call put_real(unit, 'minor_radius', [b%minor_radius], '[m] tube radius')
          call put_integer(unit, 'tube_segments', [b%tube_segments], '')
        else
          call put_note(unit, 'minor_radius, tube_segments: not used by shape '''//shape//'''')
        end if
        if (shape == 'l_prism') then
          call put_real(unit, 'thickness', [b%thickness], '[m] arm width')
        else
          call put_note(unit, 'thickness: not used by shape '''//shape//'''')
        end if
        if (shape == 'mesh') then
          call put_text(unit, 'mesh_file', b%mesh_file)
          call put_real(unit, 'scale', [b%scale], '')
        else
          call put_note(unit, 'mesh_file, scale: not used by shape '''//shape//'''')
        end if
        if (b%density > 0.0_dp) then
          call put_real(unit, 'density', [b%density], '[kg/m^3]')
          call put_note(unit, 'mass: from density')
        else if (b%mass > 0.0_dp) then
          call put_note(unit, 'density: from mass')
          call put_real(unit, 'mass', [b%mass], '[kg]')
        else
          call put_note(unit, 'density, mass: not used (fixed body)')
        end if
        call put_real(unit, 'position', b%position, '[m]')
        call put_real(unit, 'orientation', b%orientation, 'unit quaternion w, x, y, z')
        call put_real(unit, 'velocity', b%velocity, '[m/s]')
        call put_real(unit, 'angular_velocity', b%angular_velocity, '[rad/s] world frame')
        call put_logical(unit, 'fixed', b%fixed)
        call put_integer(unit, 'copies', b%copies, '')
        call put_real(unit, 'spacing', b%spacing, '[m]')
        call put_integer(unit, 'seed', [b%seed], '0: no jitter')
        call put_real(unit, 'jitter_position', [b%jitter_position], '[m]')
        call put_real(unit, 'jitter_angle', [b%jitter_angle], '[rad]')
        call put_real(unit, 'jitter_velocity', [b%jitter_velocity], '[m/s]')
        if (all(b%inertia == DECK_AUTO)) then
          call put_real(unit, 'inertia', b%inertia, '[kg m^2] -1: auto, from the geometry')
        else
          call put_real(unit, 'inertia', b%inertia, '[kg m^2] about the shape''s own axes')
        end if
        note = ''
        if (b%restitution == DECK_AUTO) note = '-1: the &contact value'
        call put_real(unit, 'restitution', [b%restitution], note)
        note = ''
        if (b%friction == DECK_AUTO) note = '-1: the &contact value'
        call put_real(unit, 'friction', [b%friction], note)
        write (unit, '(a)') '/'
      end associate
    end do
  end subroutine write_effective_deck

  subroutine put_line(unit, name, values, note)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: name, values, note
    character(len=24) :: padded
    padded = name
    if (len(note) > 0) then
      write (unit, '(a)') '  '//padded//' = '//values//'  ! '//note
    else
      write (unit, '(a)') '  '//padded//' = '//values
    end if
  end subroutine put_line

  subroutine put_real(unit, name, values, note)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: name, note
    real(dp), intent(in) :: values(:)
    character(len=:), allocatable :: text
    integer :: i
    text = real_text(values(1))
    do i = 2, size(values)
      text = text//', '//real_text(values(i))
    end do
    call put_line(unit, name, text, note)
  end subroutine put_real

  subroutine put_integer(unit, name, values, note)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: name, note
    integer, intent(in) :: values(:)
    character(len=:), allocatable :: text
    integer :: i
    text = str(values(1))
    do i = 2, size(values)
      text = text//', '//str(values(i))
    end do
    call put_line(unit, name, text, note)
  end subroutine put_integer

  subroutine put_logical(unit, name, value)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: name
    logical, intent(in) :: value
    call put_line(unit, name, str(value), '')
  end subroutine put_logical

  !> Quoted with ', a ' inside doubled.
  subroutine put_text(unit, name, value)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: name, value
    character(len=:), allocatable :: quoted
    integer :: c
    quoted = ''''
    do c = 1, len_trim(value)
      quoted = quoted//value(c:c)
      if (value(c:c) == '''') quoted = quoted//''''
    end do
    call put_line(unit, name, quoted//'''', '')
  end subroutine put_text

  subroutine put_note(unit, note)
    integer, intent(in) :: unit
    character(len=*), intent(in) :: note
    write (unit, '(a)') '  ! '//note
  end subroutine put_note

end module deck_reader
