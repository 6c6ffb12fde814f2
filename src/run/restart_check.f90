!> What a restart checks before it touches any output (docs/output.md, "Restarting"):
!>  - the checkpoint's state is sane: finite, unit quaternions, positive masses and moments,
!>    within reach of the grid (a damaged file that slipped past the digest, or a state
!>    that went bad before it was written);
!>  - its bodies are the deck's bodies: the same shape (geometry digest), group, fixed
!>    flag, mass and moments, body by body;
!>  - its deck is the deck: every variable compared; output variables and t_end may change
!>    (the continuation is then no longer bitwise the uninterrupted run), initial conditions
!>    are ignored with a notice (the state comes from the checkpoint), any other change is
!>    refused, naming the variable with its old and new value.
!> Every message names the checkpoint. Bodies here are all bodies of the run (every rank
!> holds them all while restarting), so every rank reaches the same verdict.
module restart_check
  use, intrinsic :: ieee_arithmetic, only: ieee_is_finite
  use kinds, only: dp, i8
  use constants, only: line_length
  use error_status, only: error_t, ERR_CHECKPOINT
  use string_utils, only: str, join_reals, name_index
  use input_config, only: deck_t
  use shape, only: shape_library_t
  use body_state, only: bodies_t
  use body_labels, only: body_label
  use checkpoint_meta, only: checkpoint_meta_t
  implicit none
  private
  public :: check_restored_state, check_same_bodies, compare_decks, deck_change_t

  !> |q| of a stored orientation: normalised at every update, so it is 1 to a few ulps;
  !> 1e-10 leaves room for any round-off and still catches a damaged component.
  real(dp), parameter :: unit_tolerance = 1.0e-10_dp
  !> Masses and moments are recomputed from the deck exactly as the first run did, so they
  !> agree to the last bit; 1e-12 only forgives a rebuild with other optimisation flags.
  real(dp), parameter :: property_rtol = 1.0e-12_dp
  !> A position this many grid boxes from the origin cannot be placed in the grid (its
  !> integer box coordinates are 64-bit; 2^50 keeps a wide margin).
  real(dp), parameter :: max_boxes = 2.0_dp**50

  integer, parameter :: class_refused = 0, class_allowed = 1, class_ignored = 2

  !> What compare_decks found: changes it let through, as lines for the user.
  type :: deck_change_t
    integer :: n_allowed = 0                 !< t_end, output: the run continues, not bitwise
    integer :: n_ignored = 0                 !< initial conditions: the checkpoint's state wins
    character(len=:), allocatable :: notices(:)
  end type deck_change_t

contains

  !> The restored state of every body is one a run can continue from.
  subroutine check_restored_state(deck, bodies, box_size, path, err)
    type(deck_t), intent(in) :: deck
    type(bodies_t), intent(in) :: bodies
    real(dp), intent(in) :: box_size      !< the grid's box edge [m]
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: what
    integer :: i
    do i = 1, bodies%n_owned
      what = ''
      if (.not. all(ieee_is_finite(bodies%x(:, i)))) then
        what = 'its position is not finite'
      else if (.not. all(ieee_is_finite(bodies%q(:, i)))) then
        what = 'its orientation is not finite'
      else if (abs(norm2(bodies%q(:, i)) - 1.0_dp) > unit_tolerance) then
        what = 'its orientation is not a unit quaternion (|q| - 1 = '//str(norm2(bodies%q(:, i)) - 1.0_dp, '(es9.2)')//')'
      else if (.not. all(ieee_is_finite(bodies%v(:, i)))) then
        what = 'its velocity is not finite'
      else if (.not. all(ieee_is_finite(bodies%w(:, i)))) then
        what = 'its angular velocity is not finite'
      else if (.not. (all(ieee_is_finite(bodies%a(:, i))) .and. all(ieee_is_finite(bodies%alpha(:, i))))) then
        what = 'its acceleration is not finite'
      else if (any(abs(bodies%x(:, i)) > max_boxes*box_size)) then
        what = 'its position '//str(maxval(abs(bodies%x(:, i))), '(es10.3)')//' m is beyond the grid ('// &
               str(max_boxes*box_size, '(es10.3)')//' m)'
      else if (bodies%fixed(i)) then
        if (bodies%inv_mass(i) /= 0.0_dp .or. any(bodies%inv_inertia(:, i) /= 0.0_dp)) &
          what = 'it is fixed but has a finite mass or moment of inertia'
      else if (.not. (bodies%mass(i) > 0.0_dp .and. ieee_is_finite(bodies%mass(i)))) then
        what = 'its mass '//str(bodies%mass(i), '(es10.3)')//' kg is not positive and finite'
      else if (.not. (all(bodies%inertia(:, i) > 0.0_dp) .and. all(ieee_is_finite(bodies%inertia(:, i))))) then
        what = 'its moments of inertia are not positive and finite'
      else if (abs(bodies%inv_mass(i)*bodies%mass(i) - 1.0_dp) > property_rtol .or. &
               any(abs(bodies%inv_inertia(:, i)*bodies%inertia(:, i) - 1.0_dp) > property_rtol)) then
        what = 'its inverse mass or moments do not match its mass or moments'
      end if
      if (len(what) > 0) then
        call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"' holds a state no run can continue from: "// &
                     body_label(deck, bodies, i)//': '//what)
        return
      end if
    end do
  end subroutine check_restored_state

  !> The checkpoint's bodies (saved) are the deck's (built, from the deck): the same shapes,
  !> body by body the same shape, group, fixed flag, mass and moments.
  subroutine check_same_bodies(deck, meta, saved, shapes, built, path, err)
    type(deck_t), intent(in) :: deck
    type(checkpoint_meta_t), intent(in) :: meta
    type(bodies_t), intent(in) :: saved, built
    type(shape_library_t), intent(in) :: shapes
    character(len=*), intent(in) :: path
    type(error_t), intent(inout) :: err
    integer, allocatable :: row_of(:)
    logical, allocatable :: shape_changed(:)
    character(len=:), allocatable :: where, what
    integer :: i, j, s
    where = "checkpoint '"//trim(path)//"' was not written for this deck: "
    if (size(meta%shape_digests) /= shapes%n_shapes) then
      call err%set(ERR_CHECKPOINT, where//str(size(meta%shape_digests))//' distinct shapes in the checkpoint, '// &
                   str(shapes%n_shapes)//' in the deck')
      return
    end if
    allocate (shape_changed(shapes%n_shapes))
    do s = 1, shapes%n_shapes
      shape_changed(s) = meta%shape_digests(s) /= shapes%shapes(s)%digest
    end do
    ! Rows of the built bodies by global id (the checkpoint may hold them in any order).
    allocate (row_of(built%n_owned))
    row_of = 0
    do i = 1, built%n_owned
      if (built%gid(i) >= 1 .and. built%gid(i) <= built%n_owned) row_of(built%gid(i)) = i
    end do
    do j = 1, saved%n_owned
      if (saved%gid(j) < 1 .or. saved%gid(j) > built%n_owned) then
        call err%set(ERR_CHECKPOINT, where//'it holds body id '//str(saved%gid(j))//'; the deck has ids 1..'// &
                     str(built%n_owned))
        return
      end if
      i = row_of(saved%gid(j))
      what = ''
      if (saved%group_id(j) /= built%group_id(i)) then
        what = 'it was made by &body #'//str(saved%group_id(j))//' in the checkpoint'
      else if (saved%shape_id(j) /= built%shape_id(i)) then
        what = 'its shape is shape '//str(saved%shape_id(j))//' in the checkpoint, shape '//str(built%shape_id(i))// &
               ' in the deck'
      else if (shape_changed(built%shape_id(i))) then
        s = built%shape_id(i)
        what = "its geometry differs: '"//trim(meta%shape_labels(s))//"' in the checkpoint, '"// &
               shapes%shapes(s)%label//"' in the deck (nodes and faces after welding and scaling compared)"
      else if (saved%fixed(j) .neqv. built%fixed(i)) then
        what = 'it is '//merge('fixed', 'free ', saved%fixed(j))//' in the checkpoint, '// &
               merge('fixed', 'free ', built%fixed(i))//' in the deck'
      else if (.not. built%fixed(i) .and. differs(saved%mass(j), built%mass(i))) then
        what = 'its mass is '//str(saved%mass(j), '(es23.16)')//' kg in the checkpoint, '// &
               str(built%mass(i), '(es23.16)')//' kg in the deck'
      else if (.not. built%fixed(i) .and. any([(differs(saved%inertia(s, j), built%inertia(s, i)), s=1, 3)])) then
        what = 'its principal moments are '//join_reals(saved%inertia(:, j), '(es12.5)', ', ')// &
               ' kg m^2 in the checkpoint, '//join_reals(built%inertia(:, i), '(es12.5)', ', ')//' in the deck'
      end if
      if (len(what) > 0) then
        call err%set(ERR_CHECKPOINT, where//body_label(deck, built, i)//': '//what)
        return
      end if
    end do
  end subroutine check_same_bodies

  !> Compares the effective deck of the checkpoint (old) with the run's (new), variable by
  !> variable. Refused changes end in err (every one named, old -> new); allowed and
  !> ignored ones come back as notices.
  subroutine compare_decks(old, new, path, changes, err)
    character(len=*), intent(in) :: old(:), new(:)
    character(len=*), intent(in) :: path
    type(deck_change_t), intent(out) :: changes
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: old_keys(:), old_values(:), new_keys(:), new_values(:)
    integer, allocatable :: old_at(:), new_at(:)
    character(len=:), allocatable :: refused
    character(len=line_length), allocatable :: notes(:)
    integer :: i, j, k, n_notes, n_refused
    ! (a deck of 10^5 bodies has 2 million entries: they are as wide as the decks' lines, not
    ! line_length, the notes grow as they come, and an entry is looked for first where the
    ! last one found leads, both decks being written in the same order: linear, where a
    ! search of every entry among all was quadratic, hours for 27,000 bodies)
    call split_entries(old, old_keys, old_values, old_at)
    call split_entries(new, new_keys, new_values, new_at)
    allocate (notes(16))
    n_notes = 0
    n_refused = 0
    refused = ''
    k = 0
    do i = 1, size(new_keys)
      j = find_from(old_keys, new_keys(i), k + 1)
      if (j /= 0) k = j
      if (j == 0) then
        call grow_notes()
        n_notes = n_notes + 1
        notes(n_notes) = shown_entry(new, new_at(i))//' = '//trim(new_values(i))// &
                         ' is not recorded in the checkpoint (written by an older ricochet): taken from the deck'
        changes%n_allowed = changes%n_allowed + 1
        cycle
      end if
      if (old_values(j) == new_values(i)) cycle
      select case (change_class(new_keys(i)))
      case (class_allowed)
        changes%n_allowed = changes%n_allowed + 1
        call grow_notes()
        n_notes = n_notes + 1
        notes(n_notes) = shown_entry(new, new_at(i))//' changed from '//trim(old_values(j))//' to '// &
                         trim(new_values(i))//' (allowed)'
      case (class_ignored)
        changes%n_ignored = changes%n_ignored + 1
        call grow_notes()
        n_notes = n_notes + 1
        notes(n_notes) = shown_entry(new, new_at(i))//' changed from '//trim(old_values(j))//' to '// &
                         trim(new_values(i))//': ignored, the state of the bodies comes from the checkpoint'
      case default
        n_refused = n_refused + 1
        refused = refused//'; '//shown_entry(new, new_at(i))//' '//trim(old_values(j))//' -> '//trim(new_values(i))
      end select
    end do
    i = 0
    do j = 1, size(old_keys)
      k = find_from(new_keys, old_keys(j), i + 1)
      if (k /= 0) then
        i = k
        cycle
      end if
      if (change_class(old_keys(j)) == class_refused) then
        n_refused = n_refused + 1
        refused = refused//'; '//shown_entry(old, old_at(j))//' '//trim(old_values(j))//' -> (not in this deck)'
      end if
    end do
    allocate (character(len=line_length) :: changes%notices(n_notes))
    changes%notices = notes(1:n_notes)
    if (n_refused > 0) then
      call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"': the deck changed the physics of the run ("// &
                   refused(3:)//'): a restart continues the run that wrote the checkpoint, so only t_end, '// &
                   'wall_limit and &output variables may change (docs/output.md); start a new run to change '// &
                   merge('these', 'this ', n_refused > 1))
    end if
  contains
    subroutine grow_notes()
      character(len=line_length), allocatable :: grown(:)
      if (n_notes < size(notes)) return
      allocate (grown(2*size(notes)))
      grown(1:n_notes) = notes(1:n_notes)
      call move_alloc(grown, notes)
    end subroutine grow_notes
  end subroutine compare_decks

  !> Where name is in names: at hint if it is there (the common case of two decks written
  !> in the same order), else the first place it is (0: nowhere).
  pure integer function find_from(names, name, hint) result(found)
    character(len=*), intent(in) :: names(:), name
    integer, intent(in) :: hint
    found = 0
    if (hint >= 1 .and. hint <= size(names)) then
      if (names(hint) == name) then
        found = hint
        return
      end if
    end if
    found = name_index(names, name)
  end function find_from

  !> How a change of a variable (key 'group|variable') is taken on restart.
  pure integer function change_class(key) result(class)
    character(len=*), intent(in) :: key
    character(len=len(key)) :: group, variable
    integer :: bar
    bar = index(key, '|')
    group = key(1:bar - 1)
    variable = key(bar + 1:)
    class = class_refused
    if (group == '&output') then
      class = class_allowed
    else if (group == '&parallel') then
      ! how the scene is cut over ranks: the answer is the same (docs/architecture.md)
      class = class_ignored
    else if (group == '&run') then
      if (variable == 't_end' .or. variable == 'wall_limit') class = class_allowed
    else if (group(1:5) == '&body') then
      select case (variable)
      case ('name')
        class = class_allowed
      case ('position', 'orientation', 'velocity', 'angular_velocity', 'seed', 'jitter_position', &
            'jitter_angle', 'jitter_velocity', 'mesh_file')
        ! mesh_file: its geometry is compared by digest (check_same_bodies), so a moved
        ! deck or a copied file of the same mesh is no change
        class = class_ignored
      end select
    end if
  end function change_class

  !> 'group|variable' keys and their values from effective deck lines ('&body #2' headers),
  !> and the line each is on (shown_entry names it for a message: "&body #2 'crate' size").
  subroutine split_entries(lines, keys, values, at)
    character(len=*), intent(in) :: lines(:)
    character(len=:), allocatable, intent(out) :: keys(:), values(:)
    integer, allocatable, intent(out) :: at(:)
    integer :: i, n, eq, header, key_width, value_width, pass
    ! (a key is a group header, '|' and a variable. Two passes: the first finds how many
    ! entries and how wide, so that 2 million entries of a 100,000-body deck take their own
    ! width, not the lines' or line_length; a header is kept as the line it is on.)
    key_width = 1
    value_width = 1
    do pass = 1, 2
      if (pass == 2) then
        allocate (character(len=key_width) :: keys(n))
        allocate (character(len=value_width) :: values(n))
        allocate (at(n))
      end if
      n = 0
      header = 0
      do i = 1, size(lines)
        if (lines(i)(1:1) == '&') then
          header = i
          cycle
        end if
        if (lines(i)(1:1) == '/') cycle
        eq = index(lines(i), '=')
        if (eq == 0) cycle
        n = n + 1
        if (pass == 1) then
          key_width = max(key_width, len_trim(lines(max(header, 1))) + 1 + len_trim(adjustl(lines(i)(1:eq - 1))))
          value_width = max(value_width, len_trim(adjustl(lines(i)(eq + 1:))))
        else
          if (header > 0) then
            keys(n) = lines(header)(1:len_trim(lines(header)))//'|'//trim(adjustl(lines(i)(1:eq - 1)))
          else
            keys(n) = '|'//trim(adjustl(lines(i)(1:eq - 1)))
          end if
          values(n) = adjustl(lines(i)(eq + 1:))
          at(n) = i
        end if
      end do
    end do
  end subroutine split_entries

  !> How the entry on lines(at) is named in a message: its group header, a body group's
  !> name (the line "name = '...'" inside it) and the variable.
  function shown_entry(lines, at) result(shown)
    character(len=*), intent(in) :: lines(:)
    integer, intent(in) :: at
    character(len=:), allocatable :: shown
    character(len=:), allocatable :: label
    integer :: header, k, eq
    header = 0
    do k = at - 1, 1, -1
      if (lines(k)(1:1) == '&') then
        header = k
        exit
      end if
    end do
    label = ''
    if (header > 0) then
      label = trim(lines(header))
      do k = header + 1, size(lines)
        if (lines(k)(1:1) == '/') exit
        eq = index(lines(k), '=')
        if (eq > 0) then
          if (adjustl(lines(k)(1:eq - 1)) == 'name') then
            label = label//' '//trim(adjustl(lines(k)(eq + 1:)))
            exit
          end if
        end if
      end do
    end if
    eq = index(lines(at), '=')
    shown = label//' '//trim(adjustl(lines(at)(1:eq - 1)))
  end function shown_entry

  pure logical function differs(a, b)
    real(dp), intent(in) :: a, b
    differs = .not. (abs(a - b) <= property_rtol*max(abs(a), abs(b)))
  end function differs



end module restart_check
