!> Checkpoints: a write/read round trip is bitwise exact for every body array and every
!> meta field; damaged, foreign, truncated, missing and mismatched checkpoints give
!> ERR_CHECKPOINT with the path and the reason in the message.
program test_checkpoint
  use kinds, only: dp, i8
  use constants, only: name_length
  use error_status, only: error_t, ERR_CHECKPOINT, ERR_NONE
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use shape, only: shape_t, shape_library_t, SHAPE_SPHERE
  use checkpoint_meta, only: checkpoint_meta_t, bodies_checksum, checkpoint_magic, checkpoint_version
  use checkpoint_io, only: write_checkpoint, read_checkpoint, check_checkpoint_matches
  use frame_writer, only: frame_writer_t
  use file_system, only: file_exists
  use assertions
  implicit none
  type(parallel_t) :: par
  type(error_t) :: err
  type(bodies_t) :: bodies, back
  type(checkpoint_meta_t) :: meta, meta_back, expected
  type(frame_writer_t) :: frames
  type(shape_library_t) :: shapes
  type(shape_t) :: ball
  integer :: id

  call par%init()
  call make_bodies(bodies)
  call make_meta(meta, bodies)

  ! ---- round trip: bitwise equal (compared as bit patterns, so -0.0 and 0.0 differ)
  call write_checkpoint(par, 'restart/run.h5', meta, bodies, err)
  if (err%failed() .and. index(text(err), 'without HDF5') > 0) then
    print '(a)', 'skipped: built without HDF5'
    stop 77
  end if
  call check(err%ok(), 'write: '//text(err))
  call check(file_exists('restart/run.h5'), 'write creates the folder and the file')
  call check(.not. file_exists('restart/run.h5.tmp'), 'no temporary file left')
  call read_checkpoint(par, 'restart/run.h5', meta_back, back, err)
  call check(err%ok(), 'read: '//text(err))
  call check(back%n_owned == 4 .and. back%n_ghost == 0, 'four owned bodies read')
  call check(all(back%gid(1:4) == bodies%gid(1:4)), 'gid')
  call check(all(back%shape_id(1:4) == bodies%shape_id(1:4)), 'shape_id')
  call check(all(back%group_id(1:4) == bodies%group_id(1:4)), 'group_id')
  call check(all(back%fixed(1:4) .eqv. bodies%fixed(1:4)), 'fixed')
  call check(same(back%mass(1:4), bodies%mass(1:4)), 'mass bitwise')
  call check(same(back%inv_mass(1:4), bodies%inv_mass(1:4)), 'inv_mass bitwise')
  call check(same(flat(back%inertia), flat(bodies%inertia)), 'inertia bitwise')
  call check(same(flat(back%inv_inertia), flat(bodies%inv_inertia)), 'inv_inertia bitwise')
  call check(same(flat(back%x), flat(bodies%x)), 'x bitwise')
  call check(same(flat(back%q), flat(bodies%q)), 'q bitwise')
  call check(same(flat(back%v), flat(bodies%v)), 'v bitwise')
  call check(same(flat(back%w), flat(bodies%w)), 'w bitwise')
  call check(same(flat(back%a), flat(bodies%a)), 'a bitwise')
  call check(same(flat(back%alpha), flat(bodies%alpha)), 'alpha bitwise')
  call check(meta_back%magic == checkpoint_magic .and. meta_back%version == checkpoint_version, 'magic, version')
  call check(same([meta_back%time], [meta%time]), 'time bitwise')
  call check(meta_back%step == meta%step, 'step (beyond 2^31)')
  call check(meta_back%n_frames == 3 .and. size(meta_back%frame_times) == 3, 'frame count')
  call check(same(meta_back%frame_times, meta%frame_times(1:3)), 'frame times bitwise')
  call check(same([meta_back%next_output_time, meta_back%next_checkpoint_time, meta_back%wall_time_before], &
                  [meta%next_output_time, meta%next_checkpoint_time, meta%wall_time_before]), 'schedule bitwise')
  call check(same([meta_back%e0, meta_back%p0, meta_back%l0, meta_back%mass0], [meta%e0, meta%p0, meta%l0, meta%mass0]), &
             'reference values bitwise')
  call check(meta_back%n_bodies_total == 4, 'n_bodies_total')
  call check(meta_back%title == meta%title, 'title')
  call check(same([meta_back%checksum], [meta%checksum]), 'checksum bitwise')
  call check(same(meta_back%counters, meta%counters), 'counters bitwise')
  call check(all(meta_back%counter_names == meta%counter_names), 'counter names')
  call check(size(meta_back%deck_lines) == size(meta%deck_lines), 'effective deck: as many lines')
  if (size(meta_back%deck_lines) == size(meta%deck_lines)) &
    call check(all(meta_back%deck_lines == meta%deck_lines) .and. len(meta_back%deck_lines) == 16, &
               'effective deck: the same lines, as wide as the longest')

  ! ---- version 2 (the effective deck as fixed-length strings) is still read: the same file
  ! in that layout (tests/data/make_checkpoint_fixtures.py)
  call read_checkpoint(par, test_data_path('checkpoint_version_2.h5'), meta_back, back, err)
  call check(err%ok(), 'read version 2: '//text(err))
  if (err%ok()) then
    call check(meta_back%version == 2 .and. back%n_owned == 4 .and. same(flat(back%x), flat(bodies%x)), &
               'version 2: its bodies')
    call check(size(meta_back%deck_lines) == size(meta%deck_lines), 'version 2: as many deck lines')
    if (size(meta_back%deck_lines) == size(meta%deck_lines)) &
      call check(all(meta_back%deck_lines == meta%deck_lines), 'version 2: the same deck lines')
  end if
  call err%clear()

  ! ---- a second checkpoint under the same name replaces the first
  meta%time = 2.0_dp
  call write_checkpoint(par, 'restart/run.h5', meta, bodies, err)
  call read_checkpoint(par, 'restart/run.h5', meta_back, back, err)
  call check(err%ok() .and. meta_back%time == 2.0_dp, 'overwrite an existing checkpoint')

  ! ---- the deck fingerprint
  expected%n_bodies_total = meta%n_bodies_total
  expected%title = meta%title
  expected%checksum = bodies_checksum(par, bodies)
  call check_checkpoint_matches(meta_back, expected, 'restart/run.h5', err)
  call check(err%ok(), 'checkpoint matches its own deck: '//text(err))
  expected%n_bodies_total = 5
  expected%title = 'another run'
  ! 1e-6 relative: far outside checksum_rtol (1e-9), as a changed density would be
  expected%checksum = expected%checksum*(1.0_dp + 1.0e-6_dp)
  call check_checkpoint_matches(meta_back, expected, 'restart/run.h5', err)
  call check_error(err%code, text(err), [character(len=40) :: 'restart/run.h5', 'number of bodies 4', &
                   'in the deck', "title 'test checkpoint'", "'another run'", 'checksum'], 'mismatch names every difference')
  call check(err%code == ERR_CHECKPOINT, 'mismatch is ERR_CHECKPOINT')
  call err%clear()
  expected%n_bodies_total = meta%n_bodies_total
  expected%title = meta%title
  expected%checksum = meta%checksum*(1.0_dp + 1.0e-12_dp)   ! summation-order noise is accepted
  call check_checkpoint_matches(meta_back, expected, 'restart/run.h5', err)
  call check(err%ok(), 'checksum within round-off matches')

  ! ---- failures
  call expect_failure('missing.h5', [character(len=40) :: "'missing.h5'", 'does not exist'], 'missing file')
  call truncate('restart/run.h5', 'truncated.h5')
  call expect_failure('truncated.h5', [character(len=40) :: "'truncated.h5'", 'truncated'], 'truncated file')
  call write_text('deck.nml', '&run t_end = 1.0 /')
  call expect_failure('deck.nml', [character(len=40) :: "'deck.nml'", 'not an HDF5 file'], 'a text file')
  call expect_failure(test_data_path('foreign.h5'), [character(len=40) :: 'foreign.h5', &
                      'not a ricochet checkpoint'], 'HDF5 file without the magic')
  call expect_failure(test_data_path('checkpoint_version_999.h5'), [character(len=40) :: &
                      'checkpoint_version_999.h5', 'version 999', 'reads versions 2 to 3'], 'future version')
  call expect_failure(test_data_path('checkpoint_empty.h5'), [character(len=40) :: 'checkpoint_empty.h5', &
                      'is damaged', "'time' is missing"], 'header only')
  ! A checkpoint that cannot be written (its folder would be under a file) names the path.
  call write_checkpoint(par, 'deck.nml/run.h5', meta, bodies, err)
  call check_error(err%code, text(err), [character(len=40) :: 'deck.nml'], 'unwritable checkpoint path')
  call err%clear()
  ! An output frame is HDF5 with a 'format' attribute of another kind.
  ball%kind = SHAPE_SPHERE
  ball%label = 'ball'
  ball%radius = 0.1_dp
  call shapes%add(ball, id)
  bodies%shape_id = 1
  call frames%init(par, 'output', err)
  call frames%write(par, 0.0_dp, bodies, shapes, ['b'], err)
  call check(err%ok(), 'frame written: '//text(err))
  call expect_failure('output/frames/frame_000000.h5', [character(len=40) :: 'frame_000000.h5', &
                      'not a ricochet checkpoint', "'ricochet-frame'"], 'a frame file')

  call par%free()
  call test_finish()

contains

  subroutine expect_failure(path, fragments, what)
    character(len=*), intent(in) :: path, fragments(:), what
    type(error_t) :: e
    type(checkpoint_meta_t) :: m
    type(bodies_t) :: b
    call read_checkpoint(par, path, m, b, e)
    call check_error(e%code, text(e), fragments, what)
    call check(e%code == ERR_CHECKPOINT, what//': code ERR_CHECKPOINT')
    call check(b%n_owned == 0, what//': no bodies returned')
    if (e%code == ERR_NONE) return
  end subroutine expect_failure

  function text(e) result(message)
    type(error_t), intent(in) :: e
    character(len=:), allocatable :: message
    message = ''
    if (allocated(e%message)) message = e%message
  end function text

  logical function same(a, b)
    real(dp), intent(in) :: a(:), b(:)
    same = size(a) == size(b)
    if (same) same = all(transfer(a, 0_i8, size(a)) == transfer(b, 0_i8, size(b)))
  end function same

  function flat(a) result(v)
    real(dp), intent(in) :: a(:, :)
    real(dp), allocatable :: v(:)
    v = reshape(a(:, 1:4), [size(a, 1)*4])
  end function flat

  !> Values with full 53-bit mantissas (thirds, square roots), a negative zero and a fixed body.
  subroutine make_bodies(b)
    type(bodies_t), intent(inout) :: b
    integer :: i, k
    call b%allocate(4)
    b%n_owned = 4
    b%gid = [7_i8, 3_i8, 11_i8, 5000000000_i8]
    b%shape_id = [1, 2, 1, 3]
    b%group_id = [1, 1, 2, 3]
    b%fixed = [.false., .false., .true., .false.]
    do i = 1, 4
      b%mass(i) = 1.0_dp/3.0_dp + i
      b%inv_mass(i) = 1.0_dp/b%mass(i)
      do k = 1, 3
        b%inertia(k, i) = sqrt(real(i + k, dp))
        b%inv_inertia(k, i) = 1.0_dp/b%inertia(k, i)
        b%x(k, i) = sin(real(10*i + k, dp))*1.0e3_dp
        b%v(k, i) = cos(real(10*i + k, dp))/7.0_dp
        b%w(k, i) = exp(-real(i*k, dp))
        b%a(k, i) = -9.81_dp/real(k + i, dp)
        b%alpha(k, i) = 1.0e-300_dp*real(k, dp)/3.0_dp
      end do
      b%q(:, i) = [1.0_dp, 0.1_dp*i, -0.2_dp, 0.3_dp]
      b%q(:, i) = b%q(:, i)/norm2(b%q(:, i))
    end do
    b%mass(3) = huge(1.0_dp)
    b%inv_mass(3) = 0.0_dp
    b%inv_inertia(:, 3) = 0.0_dp
    b%v(:, 3) = -0.0_dp
  end subroutine make_bodies

  subroutine make_meta(m, b)
    type(checkpoint_meta_t), intent(inout) :: m
    type(bodies_t), intent(in) :: b
    m%time = 1.0_dp/3.0_dp
    m%step = 2_i8**40 + 1
    m%n_frames = 3
    m%frame_times = [0.0_dp, 0.1_dp, 0.2_dp, 99.0_dp]   ! only the first n_frames count
    m%next_output_time = 0.3_dp
    m%next_checkpoint_time = 0.5_dp
    m%wall_time_before = 12.345_dp
    m%e0 = -1.0_dp/7.0_dp
    m%p0 = [1.0e-17_dp, 2.0_dp, -3.0_dp]
    m%l0 = [sqrt(2.0_dp), 0.0_dp, -sqrt(3.0_dp)]
    m%mass0 = 1.0_dp/9.0_dp
    m%n_bodies_total = 4
    m%title = 'test checkpoint'
    m%checksum = bodies_checksum(par, b)
    m%counters = [42.0_dp, 1.0_dp/3.0_dp]
    allocate (m%counter_names(2))
    m%counter_names = [character(len=name_length) :: 'contacts', 'events']
    ! lines of unequal length, trailing blanks (dropped), an empty line and a byte past ASCII
    m%deck_lines = [character(len=40) :: '&run', "  title = 'caf"//achar(233)//"'", '', &
                    '  t_end = 1.5     ', '/', '&body #1']
  end subroutine make_meta

  !> Copies the first half of a file: what a crash in the middle of a copy leaves.
  subroutine truncate(source, destination)
    character(len=*), intent(in) :: source, destination
    character(len=1), allocatable :: bytes(:)
    integer :: unit, size_bytes
    open (newunit=unit, file=source, access='stream', form='unformatted', status='old', action='read')
    inquire (unit=unit, size=size_bytes)
    allocate (bytes(size_bytes/2))
    read (unit) bytes
    close (unit)
    open (newunit=unit, file=destination, access='stream', form='unformatted', status='replace', action='write')
    write (unit) bytes
    close (unit)
  end subroutine truncate

  subroutine write_text(path, line)
    character(len=*), intent(in) :: path, line
    integer :: unit
    open (newunit=unit, file=path, status='replace', action='write')
    write (unit, '(a)') line
    close (unit)
  end subroutine write_text

end program test_checkpoint
