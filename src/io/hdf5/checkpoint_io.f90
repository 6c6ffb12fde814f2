!> Checkpoints (docs/output.md): everything a run needs to continue, in one HDF5 file written
!> with parallel HDF5 (each rank its owned bodies at its offset) under a temporary name and
!> renamed when complete, so a crash never leaves a half checkpoint under the real name.
!> Doubles are stored as IEEE f64: a restart continues from bitwise the same state.
!>
!> Reading checks, in this order, with ERR_CHECKPOINT and the path in every message: the
!> file exists; it opens as HDF5 (a truncated or foreign file does not); it carries the
!> 'format' attribute 'ricochet-checkpoint'; its version is one this code reads; every
!> dataset is there with the size the header announces. Whether the checkpoint fits the deck
!> is for the caller (check_checkpoint_matches).
module checkpoint_io
  use kinds, only: dp, i8
  use constants, only: name_length
  use error_status, only: error_t, ERR_CHECKPOINT, ERR_INTERNAL
  use string_utils, only: str, dirname
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use file_system, only: make_directory, rename_file, remove_file, file_exists
  use checkpoint_meta, only: checkpoint_meta_t, checkpoint_magic, checkpoint_version, checkpoint_oldest_version, &
                             check_checkpoint_matches, rows_state_digest, bodies_state_digest, deck_line_length, &
                             shape_label_length
  use h5_utils, only: hid_t, h5u_start, h5u_create_parallel, h5u_open_parallel, h5u_close_file, &
                      h5u_create_group, h5u_open_group, h5u_close_group, h5u_has_attr, h5u_write, &
                      h5u_write_strings, h5u_write_attr, h5u_read_attr, h5u_read_real_2d, h5u_read_real_1d, &
                      h5u_read_int8_1d, h5u_read_int_1d, h5u_read_strings, h5u_write_bytes, h5u_read_bytes
  implicit none
  private
  public :: write_checkpoint, read_checkpoint, check_checkpoint_matches, checkpoint_meta_t

contains

  !> Writes meta and the owned bodies of every rank to path (collective). The sum of owned
  !> bodies over ranks must be meta%n_bodies_total.
  subroutine write_checkpoint(par, path, meta, bodies, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    type(checkpoint_meta_t), intent(in) :: meta
    type(bodies_t), intent(in) :: bodies
    type(error_t), intent(inout) :: err
    integer(i8) :: n_local, n_total, offset, n_rows, n_counters
    integer(hid_t) :: file_id, group_id
    integer, allocatable :: fixed(:)
    real(dp), allocatable :: frame_times(:), counters(:)
    character(len=name_length), allocatable :: counter_names(:)
    character(len=:), allocatable :: temporary
    integer(i8), allocatable :: shape_digests(:)
    integer(i8) :: n_shapes, state_digest
    type(error_t) :: ignored
    integer :: n
    if (err%failed()) return
    n = bodies%n_owned
    state_digest = bodies_state_digest(par, bodies)
    n_local = n
    n_total = par%sum(n_local)
    offset = par%exscan(n_local)
    if (n_total /= meta%n_bodies_total) then
      call err%set(ERR_INTERNAL, "checkpoint '"//trim(path)//"': the ranks own "//str(n_total)// &
                   ' bodies but the run has '//str(meta%n_bodies_total))
      return
    end if
    if (par%is_root()) call make_directory(dirname(path), err)
    call agree(par, err, "checkpoint '"//trim(path)//"': cannot create its folder on rank 0")
    call h5u_start(err)
    if (err%failed()) return

    if (meta%n_frames > 0) then
      if (.not. allocated(meta%frame_times)) then
        call err%set(ERR_INTERNAL, "checkpoint '"//trim(path)//"': frame times missing")
      else if (size(meta%frame_times) < meta%n_frames) then
        call err%set(ERR_INTERNAL, "checkpoint '"//trim(path)//"': "//str(meta%n_frames)//' frames but '// &
                     str(size(meta%frame_times))//' frame times')
      end if
      if (err%failed()) return
    end if
    ! Small arrays are written by rank 0 alone (the others take part with no rows).
    allocate (frame_times(0), counters(0), counter_names(0))
    if (par%is_root()) then
      if (meta%n_frames > 0) frame_times = meta%frame_times(1:meta%n_frames)
      if (allocated(meta%counters)) counters = meta%counters
      if (allocated(meta%counter_names)) counter_names = meta%counter_names
    end if
    n_counters = 0
    if (allocated(meta%counters)) n_counters = size(meta%counters)
    if (allocated(meta%counter_names)) then
      if (size(meta%counter_names) /= n_counters) then
        call err%set(ERR_INTERNAL, "checkpoint '"//trim(path)//"': "//str(n_counters)//' counters but '// &
                     str(size(meta%counter_names))//' counter names')
        return
      end if
    else if (n_counters > 0) then
      call err%set(ERR_INTERNAL, "checkpoint '"//trim(path)//"': counters without names")
      return
    end if
    allocate (fixed(n))
    fixed = merge(1, 0, bodies%fixed(1:n))
    n_shapes = 0
    if (allocated(meta%shape_digests)) n_shapes = size(meta%shape_digests)
    allocate (shape_digests(0))
    if (par%is_root() .and. n_shapes > 0) shape_digests = meta%shape_digests

    temporary = trim(path)//'.tmp'
    call h5u_create_parallel(par, temporary, file_id, err)
    call h5u_write_attr(file_id, 'format', checkpoint_magic, err)
    call h5u_write_attr(file_id, 'version', checkpoint_version, err)
    call h5u_write_attr(file_id, 'time', meta%time, err)
    call h5u_write_attr(file_id, 'step', meta%step, err)
    call h5u_write_attr(file_id, 'n_frames', meta%n_frames, err)
    call h5u_write_attr(file_id, 'next_output_time', meta%next_output_time, err)
    call h5u_write_attr(file_id, 'next_checkpoint_time', meta%next_checkpoint_time, err)
    call h5u_write_attr(file_id, 'wall_time_before', meta%wall_time_before, err)
    call h5u_write_attr(file_id, 'e0', meta%e0, err)
    call h5u_write_attr(file_id, 'p0', meta%p0, err)
    call h5u_write_attr(file_id, 'l0', meta%l0, err)
    call h5u_write_attr(file_id, 'mass0', meta%mass0, err)
    call h5u_write_attr(file_id, 'n_bodies_total', meta%n_bodies_total, err)
    call h5u_write_attr(file_id, 'title', meta%title, err)
    call h5u_write_attr(file_id, 'checksum', meta%checksum, err)
    call h5u_write_attr(file_id, 'n_ranks', par%n_ranks, err)
    call h5u_write_attr(file_id, 'state_digest', state_digest, err)

    call h5u_create_group(file_id, 'meta', group_id, err)
    n_rows = meta%n_frames
    call h5u_write(group_id, 'frame_times', frame_times, n_rows, 0_i8, err)
    call h5u_write(group_id, 'counters', counters, n_counters, 0_i8, err)
    call h5u_write_strings(group_id, 'counter_names', counter_names, n_counters, 0_i8, err)
    call h5u_close_group(group_id)

    ! What made the bodies: the shapes' geometry (rank 0 writes the digests) and the effective
    ! deck (every rank a share of the lines)
    call h5u_create_group(file_id, 'shapes', group_id, err)
    call h5u_write(group_id, 'digest', shape_digests, n_shapes, 0_i8, err)
    ! (the string width is part of the collective dataset creation: the same on every rank)
    if (allocated(meta%shape_labels)) then
      call write_rows_shared(group_id, 'label', meta%shape_labels, n_shapes)
    else
      call write_rows_shared(group_id, 'label', [character(len=1) ::], n_shapes)
    end if
    call h5u_close_group(group_id)
    call h5u_create_group(file_id, 'deck', group_id, err)
    if (allocated(meta%deck_lines)) then
      call write_text_shared(group_id, meta%deck_lines)
    else
      call write_text_shared(group_id, [character(len=1) ::])
    end if
    call h5u_close_group(group_id)

    call h5u_create_group(file_id, 'bodies', group_id, err)
    call h5u_write(group_id, 'gid', bodies%gid(1:n), n_total, offset, err)
    call h5u_write(group_id, 'shape_id', bodies%shape_id(1:n), n_total, offset, err)
    call h5u_write(group_id, 'group_id', bodies%group_id(1:n), n_total, offset, err)
    call h5u_write(group_id, 'fixed', fixed, n_total, offset, err)
    call h5u_write(group_id, 'mass', bodies%mass(1:n), n_total, offset, err)
    call h5u_write(group_id, 'inv_mass', bodies%inv_mass(1:n), n_total, offset, err)
    call h5u_write(group_id, 'inertia', bodies%inertia(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'inv_inertia', bodies%inv_inertia(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'x', bodies%x(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'q', bodies%q(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'v', bodies%v(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'w', bodies%w(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'a', bodies%a(:, 1:n), n_total, offset, err)
    call h5u_write(group_id, 'alpha', bodies%alpha(:, 1:n), n_total, offset, err)
    call h5u_close_group(group_id)
    call h5u_close_file(file_id, err)
    call agree(par, err, 'writing a checkpoint failed on another rank')
    if (err%failed()) then
      call err%prefix("checkpoint '"//temporary//"': ")
      ! No .tmp left behind (every rank has closed it); an older checkpoint stays as it was.
      call par%barrier()
      if (par%is_root()) call remove_file(temporary, ignored)
      return
    end if
    ! Complete on every rank: only now may it replace an older checkpoint of the same name.
    call par%barrier()
    if (par%is_root()) call rename_file(temporary, path, err)
    call agree(par, err, 'publishing a checkpoint failed on rank 0')

  contains

    !> Every rank holds every line and writes its share, rows n_rows r/p + 1 to
    !> n_rows (r + 1)/p, all as narrow as the longest line (the string width is part of
    !> the collective dataset creation: the same on every rank). Rank 0 wrote them all
    !> before: the effective deck of 100,000 bodies (2 million lines) was a serial second
    !> of every checkpoint, copied once more to make it narrow (the lines are made as
    !> narrow as the longest already: used as they are then).
    subroutine write_rows_shared(group_id, name, lines, n_rows)
      integer(hid_t), intent(in) :: group_id
      character(len=*), intent(in) :: lines(:)
      character(len=*), intent(in) :: name
      integer(i8), intent(in) :: n_rows
      character(len=:), allocatable :: narrow(:)
      integer(i8) :: first, last
      integer :: i, width
      first = 0
      last = 0
      if (n_rows > 0 .and. size(lines, kind=i8) >= n_rows) then
        first = n_rows*par%rank/par%n_ranks
        last = n_rows*(par%rank + 1)/par%n_ranks
      end if
      width = 1
      do i = 1, int(min(n_rows, size(lines, kind=i8)))
        width = max(width, len_trim(lines(i)))
      end do
      if (width == len(lines)) then
        call h5u_write_strings(group_id, name, lines(first + 1:last), n_rows, first, err)
      else
        allocate (character(len=width) :: narrow(last - first))
        do i = 1, int(last - first)
          narrow(i) = lines(first + i)
        end do
        call h5u_write_strings(group_id, name, narrow, n_rows, first, err)
      end if
    end subroutine write_rows_shared

    !> The effective deck's lines as text (deck/text: the lines one after another, trailing
    !> blanks dropped) and deck/line_ends (line k ends at byte line_ends(k)): every rank
    !> writes its share of the lines (meta%deck_lines on writing), after the shares of the
    !> ranks before it, so that the file holds the lines in rank order (the same file on
    !> any number of ranks: the shares are blocks of the deck's groups). (As fixed-length
    !> strings every line took the longest one's 94 bytes where the mean is 37: 188 of a
    !> 211 MB checkpoint at 100,000 bodies.)
    subroutine write_text_shared(group_id, lines)
      integer(hid_t), intent(in) :: group_id
      character(len=*), intent(in) :: lines(:)
      integer(i8), allocatable :: ends(:)
      character(len=:), allocatable :: text
      integer(i8) :: n_mine, bytes_mine, first_line, first_byte
      integer :: i
      n_mine = size(lines, kind=i8)
      allocate (ends(n_mine))
      bytes_mine = 0
      do i = 1, int(n_mine)
        bytes_mine = bytes_mine + len_trim(lines(i))
        ends(i) = bytes_mine
      end do
      first_line = par%exscan(n_mine)
      first_byte = par%exscan(bytes_mine)
      allocate (character(len=int(bytes_mine)) :: text)
      do i = 1, int(n_mine)
        text(ends(i) - len_trim(lines(i)) + 1:ends(i)) = lines(i)(1:len_trim(lines(i)))
      end do
      call h5u_write_bytes(group_id, 'text', text, par%sum(bytes_mine), first_byte, err)
      call h5u_write(group_id, 'line_ends', ends + first_byte, par%sum(n_mine), first_line, err)
    end subroutine write_text_shared
  end subroutine write_checkpoint

  !> Reads a whole checkpoint on every rank (collective): all bodies come back as owned
  !> bodies of every rank (redistribution is the caller's business).
  subroutine read_checkpoint(par, path, meta, bodies, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    type(checkpoint_meta_t), intent(out) :: meta
    type(bodies_t), intent(inout) :: bodies
    type(error_t), intent(inout) :: err
    integer(hid_t) :: file_id
    character(len=:), allocatable :: format, title
    if (err%failed()) return
    if (.not. file_exists(path)) then
      call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"' does not exist")
      return
    end if
    call h5u_start(err)
    if (err%failed()) return
    call h5u_open_parallel(par, path, file_id, err)
    if (err%failed()) then
      call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"' cannot be opened as HDF5: "// &
                   'it is truncated, damaged or not an HDF5 file')
      return
    end if

    if (.not. h5u_has_attr(file_id, 'format')) then
      call err%set(ERR_CHECKPOINT, "'"//trim(path)//"' is not a ricochet checkpoint (no 'format' attribute)")
    else
      call h5u_read_attr(file_id, 'format', format, err)
      if (err%ok() .and. format /= checkpoint_magic) then
        call err%set(ERR_CHECKPOINT, "'"//trim(path)//"' is not a ricochet checkpoint (its format is '"// &
                     format//"')")
      end if
    end if
    if (err%ok()) then
      call h5u_read_attr(file_id, 'version', meta%version, err)
      if (err%ok() .and. (meta%version < checkpoint_oldest_version .or. meta%version > checkpoint_version)) then
        call err%set(ERR_CHECKPOINT, "checkpoint '"//trim(path)//"' has format version "//str(meta%version)// &
                     '; this ricochet reads versions '//str(checkpoint_oldest_version)//' to '//str(checkpoint_version))
      end if
    end if
    if (err%ok()) then
      call read_contents(file_id, meta, bodies, title, err)
      if (err%ok()) meta%title = title
    end if
    call h5u_close_file(file_id, err)
    if (err%failed()) then
      err%code = ERR_CHECKPOINT
      if (index(err%message, trim(path)) == 0) call err%prefix("checkpoint '"//trim(path)//"' is damaged: ")
    end if
  end subroutine read_checkpoint

  subroutine read_contents(file_id, meta, bodies, title, err)
    integer(hid_t), intent(in) :: file_id
    type(checkpoint_meta_t), intent(inout) :: meta
    type(bodies_t), intent(inout) :: bodies
    character(len=:), allocatable, intent(inout) :: title
    type(error_t), intent(inout) :: err
    integer(hid_t) :: group_id
    integer(i8), allocatable :: gid(:)
    integer, allocatable :: shape_id(:), group_ids(:), fixed(:)
    real(dp), allocatable :: mass(:), inv_mass(:), inertia(:, :), inv_inertia(:, :), x(:, :), q(:, :), &
                             v(:, :), w(:, :), a(:, :), alpha(:, :)
    integer :: n

    meta%magic = checkpoint_magic
    call h5u_read_attr(file_id, 'time', meta%time, err)
    call h5u_read_attr(file_id, 'step', meta%step, err)
    call h5u_read_attr(file_id, 'n_frames', meta%n_frames, err)
    call h5u_read_attr(file_id, 'next_output_time', meta%next_output_time, err)
    call h5u_read_attr(file_id, 'next_checkpoint_time', meta%next_checkpoint_time, err)
    call h5u_read_attr(file_id, 'wall_time_before', meta%wall_time_before, err)
    call h5u_read_attr(file_id, 'e0', meta%e0, err)
    call h5u_read_attr(file_id, 'p0', meta%p0, err)
    call h5u_read_attr(file_id, 'l0', meta%l0, err)
    call h5u_read_attr(file_id, 'mass0', meta%mass0, err)
    call h5u_read_attr(file_id, 'n_bodies_total', meta%n_bodies_total, err)
    call h5u_read_attr(file_id, 'title', title, err)
    call h5u_read_attr(file_id, 'checksum', meta%checksum, err)
    call h5u_read_attr(file_id, 'state_digest', meta%state_digest, err)

    call h5u_open_group(file_id, 'shapes', group_id, err)
    call h5u_read_int8_1d(group_id, 'digest', meta%shape_digests, err)
    call read_long_strings(group_id, 'label', shape_label_length, meta%shape_labels, err)
    call h5u_close_group(group_id)
    call h5u_open_group(file_id, 'deck', group_id, err)
    if (meta%version >= 3) then
      call read_text_lines(group_id, meta%deck_lines, err)
    else
      block
        character(len=deck_line_length), allocatable :: lines(:)
        call read_long_strings(group_id, 'effective', deck_line_length, lines, err)
        meta%deck_lines = compact(lines)
      end block
    end if
    call h5u_close_group(group_id)
    if (err%failed()) return
    if (size(meta%shape_labels) /= size(meta%shape_digests)) then
      call err%set(ERR_CHECKPOINT, str(size(meta%shape_digests))//' shape digests but '// &
                   str(size(meta%shape_labels))//' shape labels')
      return
    end if

    call h5u_open_group(file_id, 'meta', group_id, err)
    call h5u_read_real_1d(group_id, 'frame_times', meta%frame_times, err)
    call h5u_read_real_1d(group_id, 'counters', meta%counters, err)
    call h5u_read_strings(group_id, 'counter_names', meta%counter_names, err)
    call h5u_close_group(group_id)
    if (err%failed()) return
    if (size(meta%frame_times) /= meta%n_frames) then
      call err%set(ERR_CHECKPOINT, str(size(meta%frame_times))//' frame times for '//str(meta%n_frames)//' frames')
      return
    end if
    if (size(meta%counters) /= size(meta%counter_names)) then
      call err%set(ERR_CHECKPOINT, str(size(meta%counters))//' counters but '// &
                   str(size(meta%counter_names))//' counter names')
      return
    end if

    call h5u_open_group(file_id, 'bodies', group_id, err)
    call h5u_read_int8_1d(group_id, 'gid', gid, err)
    call h5u_read_int_1d(group_id, 'shape_id', shape_id, err)
    call h5u_read_int_1d(group_id, 'group_id', group_ids, err)
    call h5u_read_int_1d(group_id, 'fixed', fixed, err)
    call h5u_read_real_1d(group_id, 'mass', mass, err)
    call h5u_read_real_1d(group_id, 'inv_mass', inv_mass, err)
    call h5u_read_real_2d(group_id, 'inertia', 3, inertia, err)
    call h5u_read_real_2d(group_id, 'inv_inertia', 3, inv_inertia, err)
    call h5u_read_real_2d(group_id, 'x', 3, x, err)
    call h5u_read_real_2d(group_id, 'q', 4, q, err)
    call h5u_read_real_2d(group_id, 'v', 3, v, err)
    call h5u_read_real_2d(group_id, 'w', 3, w, err)
    call h5u_read_real_2d(group_id, 'a', 3, a, err)
    call h5u_read_real_2d(group_id, 'alpha', 3, alpha, err)
    call h5u_close_group(group_id)
    if (err%failed()) return
    n = size(gid)
    if (int(n, i8) /= meta%n_bodies_total .or. size(shape_id) /= n .or. size(group_ids) /= n .or. &
        size(fixed) /= n .or. size(mass) /= n .or. size(inv_mass) /= n .or. size(inertia, 2) /= n .or. &
        size(inv_inertia, 2) /= n .or. size(x, 2) /= n .or. size(q, 2) /= n .or. size(v, 2) /= n .or. &
        size(w, 2) /= n .or. size(a, 2) /= n .or. size(alpha, 2) /= n) then
      call err%set(ERR_CHECKPOINT, 'the body datasets do not all hold n_bodies_total = '// &
                   str(meta%n_bodies_total)//' rows')
      return
    end if
    call bodies%allocate(n)
    bodies%n_owned = n
    bodies%n_ghost = 0
    bodies%gid = gid
    bodies%shape_id = shape_id
    bodies%group_id = group_ids
    bodies%fixed = fixed /= 0
    bodies%mass = mass
    bodies%inv_mass = inv_mass
    bodies%inertia = inertia
    bodies%inv_inertia = inv_inertia
    bodies%x = x
    bodies%q = q
    bodies%v = v
    bodies%w = w
    bodies%a = a
    bodies%alpha = alpha
    ! Every bit of every row as written: a flipped bit or an edited value is damage.
    if (rows_state_digest(bodies) /= meta%state_digest) then
      call err%set(ERR_CHECKPOINT, 'its body data do not match the digest written with them (a changed bit '// &
                   'on disk or an edited file): use an earlier checkpoint')
    end if
  end subroutine read_contents

  !> Strings as narrow as their longest (what is written is compact whatever the width
  !> of the array held in memory).
  function compact(lines) result(narrow)
    character(len=*), intent(in) :: lines(:)
    character(len=:), allocatable :: narrow(:)
    integer :: i, width
    width = 1
    do i = 1, size(lines)
      width = max(width, len_trim(lines(i)))
    end do
    allocate (character(len=width) :: narrow(size(lines)))
    do i = 1, size(lines)
      narrow(i) = lines(i)
    end do
  end function compact

  !> Reads a list of strings into an array of the given width (longer ones are damage).
  subroutine read_long_strings(group_id, name, width, lines, err)
    integer(hid_t), intent(in) :: group_id
    character(len=*), intent(in) :: name
    integer, intent(in) :: width
    character(len=width), allocatable, intent(out) :: lines(:)
    type(error_t), intent(inout) :: err
    call h5u_read_strings(group_id, name, lines, err)
    if (err%failed() .and. .not. allocated(lines)) allocate (lines(0))
  end subroutine read_long_strings

  !> The lines of deck/text and deck/line_ends (write_text_shared), each as wide as the
  !> longest.
  subroutine read_text_lines(group_id, lines, err)
    integer(hid_t), intent(in) :: group_id
    character(len=:), allocatable, intent(out) :: lines(:)
    type(error_t), intent(inout) :: err
    character(len=:), allocatable :: text
    integer(i8), allocatable :: ends(:)
    integer(i8) :: start
    integer :: k, width
    call h5u_read_bytes(group_id, 'text', text, err)
    call h5u_read_int8_1d(group_id, 'line_ends', ends, err)
    if (err%ok()) then
      width = 1
      start = 0
      do k = 1, size(ends)
        if (ends(k) < start .or. ends(k) > len(text, kind=i8)) then
          call err%set(ERR_CHECKPOINT, "deck/line_ends("//str(k)//") = "//str(ends(k))// &
                       ' is not an end of a line of deck/text ('//str(len(text))//' bytes)')
          exit
        end if
        width = max(width, int(ends(k) - start))
        start = ends(k)
      end do
    end if
    if (err%failed()) then
      allocate (character(len=1) :: lines(0))
      return
    end if
    allocate (character(len=width) :: lines(size(ends)))
    start = 0
    do k = 1, size(ends)
      lines(k) = text(start + 1:ends(k))
      start = ends(k)
    end do
  end subroutine read_text_lines

  subroutine agree(par, err, message)
    type(parallel_t), intent(in) :: par
    type(error_t), intent(inout) :: err
    character(len=*), intent(in) :: message
    if (par%any(err%failed()) .and. err%ok()) call err%set(ERR_CHECKPOINT, message)
  end subroutine agree

end module checkpoint_io
