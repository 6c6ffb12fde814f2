!> The namelist machinery shared by every group reader of deck_reader (docs/input.md), i.e.
!> everything that does not belong to one group: steps 1 to 3 of deck_reader's "how a deck
!> is read" (the deck in memory, the scan for its groups and the check of their structure,
!> one group's assignments split and checked before Fortran sees them) and, for step 4, the
!> translation of a failed namelist READ; then what a group gives and on which line
!> (given, var_line, ...), the messages that name the deck, the line and the group (fail,
!> fail_at), and the lines of the effective deck (real_text: the shortest decimal that
!> reads back; put_*: one 'name = values' line). Each group's variables, defaults, namelist
!> READ and rules live in its own reader (run_group, integrator_group, contact_group,
!> output_group, body_group).
module namelist_source
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use, intrinsic :: iso_c_binding, only: c_char, c_ptr, c_double, c_int, c_null_char, c_null_ptr
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INPUT, ERR_IO
  use string_utils, only: str, decimal_digits, lower, name_index
  use deck_sink, only: deck_sink_t
  implicit none
  private
  public :: DECK_AUTO, V_REAL, V_INTEGER, V_LOGICAL, V_CHARACTER, T_WORD, T_STRING, T_EQUALS
  public :: var_spec_t, token_t, group_t, source_t, group_input_t
  public :: load_source, scan_groups, check_group_structure
  public :: open_group, tokenize, check_assignments, prepare_group, translate_read_error
  public :: given, given_element, first_element_line, var_line, fail, fail_at, require_finite, suggestion
  public :: real_text, put_real, put_integer, put_logical, put_text, put_note

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

  character(len=*), parameter :: known_groups = '&run, &integrator, &contact, &output, &parallel, &body'
  character(len=10), parameter :: group_names(6) = [character(len=10) :: &
    'run', 'integrator', 'contact', 'output', 'parallel', 'body']

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
      j = name_index(group_names, src%groups(k)%name)
      if (j == 0) then
        call err%set(ERR_INPUT, src%path//':'//str(src%groups(k)%first_line)//': unknown group ''&'// &
                     src%groups(k)%name//''''//suggestion(src%groups(k)%name, group_names, '&')// &
                     ' (known groups: '//known_groups//')')
        return
      end if
      if (first(j) /= 0 .and. src%groups(k)%name /= 'body') then
        call err%set(ERR_INPUT, src%path//':'//str(src%groups(k)%first_line)//': &'//src%groups(k)%name// &
                     ' appears again (first at line '//str(first(j))// &
                     '); &run, &integrator, &contact, &output and &parallel may each appear once')
        return
      end if
      if (first(j) == 0) first(j) = src%groups(k)%first_line
    end do
    if (first(1) == 0) then
      call err%set(ERR_INPUT, src%path//': no &run group: a deck needs &run with t_end and dt_max')
    else if (first(name_index(group_names, 'body')) == 0) then
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
  !> Effective decks write a dozen reals per body at every checkpoint, so this is fast: one
  !> formatted write of 21 significant digits (correctly rounded, as every write of gfortran
  !> is), candidates of 1 to 17 digits rounded from that string, and each tried with C's
  !> strtod (what a Fortran READ of a real calls: correctly rounded). Rounding a correctly
  !> rounded string again is the direct rounding except when the digits cut off are exactly
  !> 5000...: that case takes the reference test, one write and one READ per number of
  !> digits (shortest_digits). Both give the same text (tests/io/test_deck_text checks it on
  !> random and edge values).
  function real_text(x, by_io) result(text)
    real(dp), intent(in) :: x
    !> the reference path only (the unit test's comparison)
    logical, intent(in), optional :: by_io
    character(len=:), allocatable :: text
    character(len=20) :: digits
    integer :: n_digits, exponent
    logical :: io

    if (.not. ieee_is_finite(x)) then
      block
        character(len=48) :: buffer
        write (buffer, '(g0)') x
        text = trim(adjustl(buffer))
      end block
      return
    end if
    if (x == 0.0_dp) then
      text = merge('-0.0', ' 0.0', sign(1.0_dp, x) < 0.0_dp)
      text = trim(adjustl(text))
      return
    end if
    io = .false.
    if (present(by_io)) io = by_io
    if (.not. io .and. abs(x) < 2.0_dp**53 .and. x == aint(x)) then
      ! An integral value below 2^53 (most deck defaults: -1, 1, 1000): its shortest digits
      ! are its own, trailing zeros dropped, since every other decimal with as few digits
      ! is at least 1 away and doubles there are at most 1 apart.
      call integral_digits(int(abs(x), i8), digits, n_digits, exponent)
    else
      call shortest_digits(abs(x), io, digits, n_digits, exponent)
    end if
    text = decimal_text(digits(1:n_digits), exponent)
    if (x < 0.0_dp) text = '-'//text
  end function real_text

  !> The decimal digits of m > 0 without its trailing zeros, and the exponent of the first
  !> (m = digits(1:n) x 10^(exponent - n + 1)), as shortest_digits gives them.
  pure subroutine integral_digits(m, digits, n, exponent)
    integer(i8), intent(in) :: m
    character(len=20), intent(out) :: digits
    integer, intent(out) :: n, exponent
    character(len=20) :: reversed
    integer(i8) :: rest
    integer :: k, length
    rest = m
    length = 0
    do while (rest > 0)
      length = length + 1
      reversed(length:length) = achar(iachar('0') + int(mod(rest, 10_i8)))
      rest = rest/10_i8
    end do
    exponent = length - 1
    digits = ''
    do k = 1, length
      digits(k:k) = reversed(length - k + 1:length - k + 1)
    end do
    n = length
    do while (n > 1 .and. digits(n:n) == '0')
      n = n - 1
    end do
  end subroutine integral_digits

  !> The fewest significant digits (digits(1:n), first nonzero, last nonzero unless n = 1)
  !> and the decimal exponent of the first such that digits * 10^(exponent - n + 1) reads
  !> back as x (x > 0, finite); see real_text. One search (1 to 3 digits, then a bisection
  !> of 4 to 17: round-tripping is monotone in the number of digits but at some powers of
  !> two, whose rounding interval is uneven, so both paths must search alike) over either
  !> test of a candidate: by_io, the reference (a write of p digits and a READ of it), else
  !> the fast one (p digits rounded from one 21-digit write, tried with strtod), which
  !> hands the search to the reference where its rounding is in doubt.
  subroutine shortest_digits(x, by_io, digits, n, exponent)
    real(dp), intent(in) :: x
    logical, intent(in) :: by_io
    character(len=20), intent(out) :: digits
    integer, intent(out) :: n, exponent
    integer, parameter :: long = 21
    character(len=48) :: buffer
    character(len=24) :: fmt
    character(len=long) :: exact
    character(len=long + 1) :: rounded
    integer :: e_exact, e_p, first, low, high, middle
    logical :: io, doubt, ok
    io = by_io
    if (.not. io) then
      call digits21(x, buffer)
      call split_mantissa(buffer, exact, e_exact)
    end if
    ! Near the top of the range fewer digits could round up past huge() and overflow.
    first = 1
    if (x > 1.0e307_dp) first = 17
    do
      doubt = .false.
      n = 0
      do low = first, 3
        if (try(low)) then
          n = low
          exit
        end if
      end do
      if (n == 0) then
        low = max(first, 4)
        high = 17
        do while (low < high)
          middle = (low + high)/2
          if (try(middle)) then
            high = middle
          else
            low = middle + 1
          end if
        end do
        n = low
      end if
      if (.not. doubt) ok = try(n)      ! (rounded, e_p: the digits found)
      if (.not. doubt) exit
      io = .true.
    end do
    do while (n > 1 .and. rounded(n:n) == '0')
      n = n - 1
    end do
    digits = rounded(1:n)
    exponent = e_p
  contains
    !> rounded(1:p), e_p: x to p significant digits; whether they read back as x. The fast
    !> test is in doubt (doubt set, false returned) where the digits cut off are exactly
    !> 5000...: the 21-digit string may itself have been rounded to that half, so its
    !> rounding to p digits is not known.
    logical function try(p)
      integer, intent(in) :: p
      integer :: k, ios
      real(dp) :: back
      try = .false.
      if (io) then
        write (fmt, '(a,i0,a)') '(es48.', p - 1, 'e4)'
        write (buffer, fmt) x
        read (buffer, *, iostat=ios) back
        call split_mantissa(buffer, rounded, e_p)
        try = ios == 0 .and. back == x
        return
      end if
      if (doubt) return
      if (exact(p + 1:p + 1) == '5' .and. verify(exact(p + 2:long), '0') == 0) then
        doubt = .true.
        return
      end if
      rounded = '0'//exact(1:p)
      e_p = e_exact
      if (exact(p + 1:p + 1) >= '5') then
        k = p + 1
        do
          if (rounded(k:k) == '9') then
            rounded(k:k) = '0'
            k = k - 1
          else
            rounded(k:k) = achar(iachar(rounded(k:k)) + 1)
            exit
          end if
        end do
      end if
      if (rounded(1:1) == '1') then
        e_p = e_exact + 1
        rounded = rounded(1:p)
      else
        rounded = rounded(2:p + 1)
      end if
      try = reads_back(rounded(1:p), e_p, x)
    end function try
  end subroutine shortest_digits

  !> x (finite, > 0) as 'd.dddddddddddddddddddde+xx': 21 significant digits, correctly
  !> rounded (C's printf, exact as the ES edit descriptor is; decimal_digits.c).
  subroutine digits21(x, buffer)
    real(dp), intent(in) :: x
    character(len=*), intent(out) :: buffer
    interface
      function c_digits21(value, text, size) bind(c, name='ricochet_decimal_digits21') result(length)
        import :: c_double, c_char, c_int
        real(c_double), value :: value
        character(kind=c_char), intent(out) :: text(*)
        integer(c_int), value :: size
        integer(c_int) :: length
      end function c_digits21
    end interface
    character(kind=c_char) :: text(48)
    integer :: n, k
    n = c_digits21(real(x, c_double), text, int(size(text), c_int))
    buffer = ' '
    if (n <= 0) then
      write (buffer, '(es48.20e4)') x     ! (not reached for finite x: the Fortran edit)
      return
    end if
    do k = 1, min(n, len(buffer))
      buffer(k:k) = text(k)
    end do
  end subroutine digits21

  !> The digits (no dot) and the exponent of an ES-edited positive number ('1.25E+0003'),
  !> read without formatted I/O.
  subroutine split_mantissa(edited, mantissa, exponent)
    character(len=*), intent(in) :: edited
    character(len=*), intent(out) :: mantissa
    integer, intent(out) :: exponent
    character(len=len(edited)) :: text
    integer :: e_pos, k
    text = adjustl(edited)
    e_pos = scan(text, 'Ee')
    mantissa = text(1:1)//text(3:e_pos - 1)
    exponent = 0
    do k = e_pos + 2, len_trim(text)
      exponent = 10*exponent + (iachar(text(k:k)) - iachar('0'))
    end do
    if (text(e_pos + 1:e_pos + 1) == '-') exponent = -exponent
  end subroutine split_mantissa

  !> Whether 0.d x 10^(e + 1) (the digits d given, d(1) the units digit of d.ddd x 10^e)
  !> reads back as x: C's strtod, correctly rounded as a Fortran READ is (no formatted I/O
  !> here: that is what made the reference path slow).
  logical function reads_back(d, e, x)
    character(len=*), intent(in) :: d
    integer, intent(in) :: e
    real(dp), intent(in) :: x
    interface
      function c_strtod(text, end) bind(c, name='strtod') result(value)
        import :: c_char, c_ptr, c_double
        character(kind=c_char), intent(in) :: text(*)
        type(c_ptr), value :: end
        real(c_double) :: value
      end function c_strtod
    end interface
    ! the candidate '0.<d>e<e + 1>' in a fixed buffer (the heap strings of a concatenation
    ! were a fifth of writing 100,000 bodies' effective deck: 4 candidates per real)
    character(kind=c_char) :: text(48)
    character(len=12) :: power
    integer :: k, n, first
    call decimal_digits(int(e + 1, i8), power, first)
    text(1) = '0'
    text(2) = '.'
    n = 2
    do k = 1, len(d)
      text(n + k) = d(k:k)
    end do
    n = n + len(d) + 1
    text(n) = 'e'
    do k = first, len(power)
      text(n + k - first + 1) = power(k:k)
    end do
    n = n + len(power) - first + 1
    text(n + 1) = c_null_char
    reads_back = c_strtod(text, c_null_ptr) == x
  end function reads_back

  !> Deck text of the decimal d.ddd x 10^exponent (d: significant digits, no trailing zero
  !> but the only one): plain notation for exponents -4 to 7 ('0.00025', '9.81', '1000.0'),
  !> else 'd.ddde<exponent>' ('1.0e-14').
  pure function decimal_text(digits, exponent) result(text)
    character(len=*), intent(in) :: digits
    integer, intent(in) :: exponent
    character(len=:), allocatable :: text
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
  end function decimal_text


  ! ---------------------------------------------------------------------------------------
  ! Lines of the effective deck
  ! ---------------------------------------------------------------------------------------

  subroutine put_line(out, name, values, note)
    type(deck_sink_t), intent(inout) :: out
    character(len=*), intent(in) :: name, values, note
    character(len=24) :: padded
    padded = name
    if (len(note) > 0) then
      call out%put('  '//padded//' = '//values//'  ! '//note)
    else
      call out%put('  '//padded//' = '//values)
    end if
  end subroutine put_line

  subroutine put_real(out, name, values, note)
    type(deck_sink_t), intent(inout) :: out
    character(len=*), intent(in) :: name, note
    real(dp), intent(in) :: values(:)
    character(len=:), allocatable :: text
    integer :: i
    text = real_text(values(1))
    do i = 2, size(values)
      text = text//', '//real_text(values(i))
    end do
    call put_line(out, name, text, note)
  end subroutine put_real

  subroutine put_integer(out, name, values, note)
    type(deck_sink_t), intent(inout) :: out
    character(len=*), intent(in) :: name, note
    integer, intent(in) :: values(:)
    character(len=:), allocatable :: text
    integer :: i
    text = str(values(1))
    do i = 2, size(values)
      text = text//', '//str(values(i))
    end do
    call put_line(out, name, text, note)
  end subroutine put_integer

  subroutine put_logical(out, name, value)
    type(deck_sink_t), intent(inout) :: out
    character(len=*), intent(in) :: name
    logical, intent(in) :: value
    call put_line(out, name, str(value), '')
  end subroutine put_logical

  !> Quoted with ', a ' inside doubled.
  subroutine put_text(out, name, value)
    type(deck_sink_t), intent(inout) :: out
    character(len=*), intent(in) :: name, value
    character(len=:), allocatable :: quoted
    integer :: c
    quoted = ''''
    do c = 1, len_trim(value)
      quoted = quoted//value(c:c)
      if (value(c:c) == '''') quoted = quoted//''''
    end do
    call put_line(out, name, quoted//'''', '')
  end subroutine put_text

  subroutine put_note(out, note)
    type(deck_sink_t), intent(inout) :: out
    character(len=*), intent(in) :: note
    call out%put('  ! '//note)
  end subroutine put_note

end module namelist_source
