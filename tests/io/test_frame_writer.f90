!> Frame output: three frames of three bodies (an analytic sphere and two copies of a
!> hand-made box mesh whose principal frame is turned against its own frame), the XDMF
!> indexes in blocks of two frames (a finished block included from its own file), restart
!> of the frame list. The companion check_xdmf.py (io.frame_writer_xdmf)
!> then opens the result with VTK's XDMF reader, as ParaView does, and checks the values.
program test_frame_writer
  use kinds, only: dp, i8
  use constants, only: pi
  use error_status, only: error_t
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use shape, only: shape_t, shape_library_t, SHAPE_SPHERE, SHAPE_MESH
  use quaternion, only: quat_exp, quat_mul, quat_conj
  use frame_writer, only: frame_writer_t
  use file_system, only: file_exists
  use assertions
  implicit none
  type(parallel_t) :: par
  type(error_t) :: err
  type(shape_library_t) :: shapes
  type(bodies_t) :: bodies
  type(frame_writer_t) :: writer, restarted
  character(len=16) :: group_names(2)
  real(dp), parameter :: dt = 0.1_dp
  integer :: frame

  call par%init()
  call make_shapes(shapes)
  call make_bodies(bodies)
  group_names = [character(len=16) :: 'ball', 'crate']

  call writer%init(par, 'output', err)
  if (err%failed() .and. index(err%message, 'without HDF5') > 0) then
    print '(a)', 'skipped: built without HDF5'
    stop 77
  end if
  call check(err%ok(), 'init: '//message(err))
  call check(file_exists('output/frames'), 'init creates output/frames')
  writer%block_frames = 2
  call remove_file('output/frames/surfaces_block_000000.xmf')   ! of an earlier run of this test

  ! Frame 0 of a first run: listed in the index itself.
  call move_to(bodies, 0.0_dp)
  call writer%write(par, 0.0_dp, bodies, shapes, group_names, err)
  call check(err%ok(), 'write frame 0: '//message(err))
  call check(count_in_file('output/surfaces.xmf', '<Time ') == 1, 'surfaces.xmf lists frame 0')
  call check(.not. file_exists('output/frames/surfaces_block_000000.xmf'), 'no block file before the block is full')
  ! Frame 1 completes block 0: its two grids move into frames/{surfaces,bodies}_block_000000.xmf.
  call move_to(bodies, dt)
  call writer%write(par, dt, bodies, shapes, group_names, err)
  call check(err%ok(), 'write frame 1: '//message(err))
  call check(writer%n_frames == 2, 'two frames counted')
  call check(count_in_file('output/surfaces.xmf', '<Time ') == 0, 'surfaces.xmf lists no frame itself')
  call check(count_in_file('output/surfaces.xmf', 'href="frames/surfaces_block_000000.xmf"') == 1, &
             'surfaces.xmf includes block 0')
  call check(count_in_file('output/bodies.xmf', 'href="frames/bodies_block_000000.xmf"') == 1, &
             'bodies.xmf includes block 0')
  call check(count_in_file('output/frames/surfaces_block_000000.xmf', '<Time ') == 2, 'block 0 lists two frames')
  call check(count_in_file('output/frames/bodies_block_000000.xmf', '<Time ') == 2, 'block 0 of bodies lists two')
  call check(.not. file_exists('output/frames/frame_000001.h5.tmp'), 'no temporary frame left')
  call check(.not. file_exists('output/surfaces.xmf.tmp'), 'no temporary index left')
  call check(.not. file_exists('output/frames/surfaces_block_000000.xmf.tmp'), 'no temporary block left')
  ! Then a "crash" after two frames at wrong times that the restart must replace, the
  ! second of which completes block 1: its block file lists the wrong times.
  do frame = 2, 3
    call move_to(bodies, 5.0_dp*frame)
    call writer%write(par, 5.0_dp*frame, bodies, shapes, group_names, err)
  end do
  call check(err%ok() .and. writer%n_frames == 4, 'two frames after the checkpoint')
  call check(count_in_file('output/frames/surfaces_block_000001.xmf', '1.0000000000000000E+001') == 1, &
             'the stale block 1 on disk')

  ! Restart from a checkpoint taken after frame 1: frame 2 is written again, and the
  ! indexes then list frames 0, 1 (sizes read back from their files) and the new frame 2.
  call restarted%init(par, 'output', err)
  restarted%block_frames = 2
  call restarted%restore(2, writer%frame_times(1:2))
  call check(restarted%n_frames == 2, 'restored two frames')
  call check(all(restarted%frame_times(1:2) == [0.0_dp, dt]), 'restored frame times')
  call move_to(bodies, 2*dt)
  call restarted%write(par, 2*dt, bodies, shapes, group_names, err)
  call check(err%ok(), 'write frame 2 after restart: '//message(err))
  call check(restarted%n_frames == 3, 'three frames after the restart')
  call check(all(restarted%frame_sizes(:, 1:3) == spread([3_i8, 178_i8, 344_i8], 2, 3)), &
             'sizes of the restored frames read back')
  ! Block 0 (frames 0, 1) included, frame 2 listed, the stale block 1 not referenced.
  call check(count_in_file('output/surfaces.xmf', '<Time ') == 1, 'surfaces.xmf lists frame 2 itself')
  call check(count_in_file('output/bodies.xmf', '<Time ') == 1, 'bodies.xmf lists frame 2 itself')
  call check(count_in_file('output/surfaces.xmf', '<xi:include ') == 1, 'surfaces.xmf includes block 0 only')
  call check(count_in_file('output/frames/surfaces_block_000000.xmf', '<Time ') == 2, 'block 0 lists two frames')
  call check(count_in_file('output/frames/surfaces_block_000000.xmf', 'NumberOfElements="344"') == 2 .and. &
             count_in_file('output/surfaces.xmf', 'NumberOfElements="344"') == 1, 'triangle counts in the indexes')
  call check(count_in_file('output/bodies.xmf', 'frames/frame_000002.h5:/bodies/position') == 1, &
             'bodies.xmf points at frame 2 by a relative path')
  call check(count_in_file('output/frames/bodies_block_000000.xmf', 'frames/frame_000001.h5:/bodies/position') == 1, &
             'a block points at its frames by paths relative to the index')
  call check(count_in_file('output/surfaces.xmf', '1.0000000000000000E+001') == 0, &
             'the replaced frame time is gone')

  ! Restoring frames whose files are missing names the file at the next write.
  call writer%init(par, 'output_empty', err)
  call writer%restore(1, [0.0_dp])
  call writer%write(par, dt, bodies, shapes, group_names, err)
  call check_error(err%code, message(err), [character(len=40) :: 'output_empty/frames/frame_000000.h5'], &
                   'restore with a missing frame file')
  call err%clear()

  ! An output folder that cannot be made (its parent is a file) is named in the error.
  open (newunit=frame, file='plain_file', status='replace', action='write')
  close (frame)
  call writer%init(par, 'plain_file/output', err)
  call check_error(err%code, message(err), [character(len=40) :: "'plain_file/output/frames'"], &
                   'output folder under a file')
  call err%clear()

  call writer%free()
  call restarted%free()
  call par%free()
  call test_finish()

contains

  function message(e) result(text)
    type(error_t), intent(in) :: e
    character(len=:), allocatable :: text
    text = ''
    if (allocated(e%message)) text = e%message
  end function message

  !> Shape 1: sphere r = 0.5 m. Shape 2: box 1 x 2 x 3 m (nodes at +-0.5, +-1, +-1.5) stored in
  !> its principal frame, which is turned by q_principal = 90 degrees about z against the
  !> box's own frame (as a shape builder would after diagonalising the inertia).
  subroutine make_shapes(lib)
    type(shape_library_t), intent(inout) :: lib
    type(shape_t) :: s
    integer :: id
    real(dp) :: nodes(3, 8)
    integer :: faces(3, 12)
    s%kind = SHAPE_SPHERE
    s%label = 'sphere r=0.5'
    s%radius = 0.5_dp
    call lib%add(s, id)
    nodes = reshape([-0.5_dp, -1.0_dp, -1.5_dp, 0.5_dp, -1.0_dp, -1.5_dp, 0.5_dp, 1.0_dp, -1.5_dp, &
                     -0.5_dp, 1.0_dp, -1.5_dp, -0.5_dp, -1.0_dp, 1.5_dp, 0.5_dp, -1.0_dp, 1.5_dp, &
                     0.5_dp, 1.0_dp, 1.5_dp, -0.5_dp, 1.0_dp, 1.5_dp], [3, 8])
    faces = reshape([1, 3, 2, 1, 4, 3, 5, 6, 7, 5, 7, 8, 1, 2, 6, 1, 6, 5, &
                     2, 3, 7, 2, 7, 6, 3, 4, 8, 3, 8, 7, 4, 1, 5, 4, 5, 8], [3, 12])
    s%kind = SHAPE_MESH
    s%label = 'box 1x2x3'
    s%radius = 0.0_dp
    call s%mesh%init(nodes, faces, 'test box')
    s%q_principal = quat_exp([0.0_dp, 0.0_dp, 0.5_dp*pi])
    call lib%add(s, id)
  end subroutine make_shapes

  !> gid 1: the sphere; gids 2, 3: boxes. The values are repeated in check_xdmf.py.
  subroutine make_bodies(b)
    type(bodies_t), intent(inout) :: b
    call b%allocate(3)
    b%n_owned = 3
    b%gid = [1_i8, 2_i8, 3_i8]
    b%shape_id = [1, 2, 2]
    b%group_id = [1, 2, 2]
    b%mass = [1.0_dp, 6.0_dp, 6.0_dp]
    b%v(:, 1) = [0.0_dp, 0.0_dp, -1.0_dp]
    b%v(:, 2) = [1.0_dp, 0.0_dp, 0.0_dp]
    b%v(:, 3) = [0.0_dp, 2.0_dp, 0.0_dp]
    b%w(:, 1) = [0.0_dp, 0.0_dp, 0.0_dp]
    b%w(:, 2) = [0.0_dp, 0.0_dp, 1.0_dp]
    b%w(:, 3) = [0.5_dp, 0.0_dp, 0.0_dp]
    ! principal -> world: box 3 is turned 90 degrees about x
    b%q(:, 3) = quat_exp([0.5_dp*pi, 0.0_dp, 0.0_dp])
  end subroutine make_bodies

  !> Straight-line motion from fixed start points (orientation kept: the output only has to
  !> show what it is given).
  subroutine move_to(b, t)
    type(bodies_t), intent(inout) :: b
    real(dp), intent(in) :: t
    b%x(:, 1) = [0.0_dp, 0.0_dp, 3.0_dp] + t*b%v(:, 1)
    b%x(:, 2) = [2.0_dp, 0.0_dp, 0.0_dp] + t*b%v(:, 2)
    b%x(:, 3) = [-2.0_dp, 0.0_dp, 0.0_dp] + t*b%v(:, 3)
  end subroutine move_to

  subroutine remove_file(path)
    character(len=*), intent(in) :: path
    integer :: unit, status
    open (newunit=unit, file=path, status='old', iostat=status)
    if (status == 0) close (unit, status='delete')
  end subroutine remove_file

  integer function count_in_file(path, text) result(n)
    character(len=*), intent(in) :: path, text
    character(len=1024) :: line
    integer :: unit, status
    n = 0
    open (newunit=unit, file=path, status='old', action='read', iostat=status)
    if (status /= 0) return
    do
      read (unit, '(a)', iostat=status) line
      if (status /= 0) exit
      if (index(line, text) > 0) n = n + 1
    end do
    close (unit)
  end function count_in_file

end program test_frame_writer
