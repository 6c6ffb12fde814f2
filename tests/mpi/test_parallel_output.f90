! ctest-ranks: 2
!> Frames and checkpoints from two ranks, each owning part of the bodies (rank 0: gids 1, 3,
!> 5; rank 1: gids 2, 4), written with collective hyperslab writes and read back on every
!> rank; then once more with all bodies on rank 0 and none on rank 1. The frame's contents
!> are checked by check_parallel_frame.py (mpi.parallel_frame_contents).
program test_parallel_output
  use kinds, only: dp, i8
  use constants, only: name_length
  use error_status, only: error_t
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use shape, only: shape_t, shape_library_t, SHAPE_SPHERE, SHAPE_MESH
  use checkpoint_meta, only: checkpoint_meta_t, bodies_checksum
  use checkpoint_io, only: write_checkpoint, read_checkpoint, check_checkpoint_matches
  use frame_writer, only: frame_writer_t
  use file_system, only: file_exists
  use assertions
  implicit none
  type(parallel_t) :: par
  type(error_t) :: err
  type(shape_library_t) :: shapes
  type(bodies_t) :: bodies, back
  type(checkpoint_meta_t) :: meta, meta_back
  type(frame_writer_t) :: writer
  integer(i8), allocatable :: mine(:)
  integer :: i, k
  logical :: ok

  call par%init()
  call check(par%n_ranks == 2, 'runs on two ranks')
  call make_shapes(shapes)
  if (par%rank == 0) then
    mine = [1_i8, 3_i8, 5_i8]
  else
    mine = [2_i8, 4_i8]
  end if
  call make_bodies(mine, bodies)

  ! ---- a frame from both ranks
  call writer%init(par, 'output', err)
  if (err%failed() .and. index(text(err), 'without HDF5') > 0) then
    print '(a)', 'skipped: built without HDF5'
    stop 77
  end if
  call writer%write(par, 0.5_dp, bodies, shapes, ['odd ', 'even'], err)
  call check(err%ok(), 'frame from two ranks: '//text(err))
  call check(file_exists('output/frames/frame_000000.h5'), 'frame file published')
  call check(all(writer%frame_sizes(:, 1) == [5_i8, 4*162_i8 + 8, 4*320_i8 + 12]), &
             'frame holds 5 bodies, 656 points, 1292 triangles')

  ! ---- a checkpoint from both ranks, read on both
  meta%time = 0.5_dp
  meta%n_bodies_total = 5
  meta%title = 'two ranks'
  meta%checksum = bodies_checksum(par, bodies)
  call write_checkpoint(par, 'ckpt/two_ranks.h5', meta, bodies, err)
  call check(err%ok(), 'checkpoint from two ranks: '//text(err))
  call read_checkpoint(par, 'ckpt/two_ranks.h5', meta_back, back, err)
  call check(err%ok(), 'checkpoint read on rank '//achar(48 + par%rank)//': '//text(err))
  call check(back%n_owned == 5, 'every rank gets all five bodies')
  ! rows are rank 0's bodies, then rank 1's
  call check(all(back%gid(1:5) == [1_i8, 3_i8, 5_i8, 2_i8, 4_i8]), 'rows in rank order')
  call check(all_bodies_exact(back), 'every body exactly as written')
  call check_checkpoint_matches(meta_back, meta, 'ckpt/two_ranks.h5', err)
  call check(err%ok(), 'fingerprint matches')

  ! ---- all bodies on rank 0, none on rank 1 (an empty rank still takes part)
  call bodies%free()
  if (par%rank == 0) then
    call make_bodies([5_i8, 4_i8, 3_i8, 2_i8, 1_i8], bodies)
  else
    call make_bodies([integer(i8) ::], bodies)
  end if
  call writer%write(par, 1.0_dp, bodies, shapes, ['odd ', 'even'], err)
  call check(err%ok(), 'frame with an empty rank: '//text(err))
  call write_checkpoint(par, 'ckpt/uneven.h5', meta, bodies, err)
  call check(err%ok(), 'checkpoint with an empty rank: '//text(err))
  call read_checkpoint(par, 'ckpt/uneven.h5', meta_back, back, err)
  call check(err%ok() .and. back%n_owned == 5, 'uneven checkpoint read')
  call check(all(back%gid(1:5) == [5_i8, 4_i8, 3_i8, 2_i8, 1_i8]), 'uneven: rows of rank 0')
  call check(all_bodies_exact(back), 'uneven: every body exactly as written')
  ok = par%any(.false.)   ! both ranks finish their checks before the files are inspected

  call par%free()
  call test_finish()

contains

  function text(e) result(message)
    type(error_t), intent(in) :: e
    character(len=:), allocatable :: message
    message = ''
    if (allocated(e%message)) message = e%message
  end function text

  !> Shape 1: sphere r = 0.25 m; shape 2: box 0.2 x 0.4 x 0.6 m (in check_parallel_frame.py too).
  subroutine make_shapes(lib)
    type(shape_library_t), intent(inout) :: lib
    type(shape_t) :: s
    integer :: id
    s%kind = SHAPE_SPHERE
    s%label = 'sphere'
    s%radius = 0.25_dp
    call lib%add(s, id)
    s%kind = SHAPE_MESH
    s%label = 'box'
    call s%mesh%init(reshape([-0.1_dp, -0.2_dp, -0.3_dp, 0.1_dp, -0.2_dp, -0.3_dp, 0.1_dp, 0.2_dp, -0.3_dp, &
                              -0.1_dp, 0.2_dp, -0.3_dp, -0.1_dp, -0.2_dp, 0.3_dp, 0.1_dp, -0.2_dp, 0.3_dp, &
                              0.1_dp, 0.2_dp, 0.3_dp, -0.1_dp, 0.2_dp, 0.3_dp], [3, 8]), &
                     reshape([1, 3, 2, 1, 4, 3, 5, 6, 7, 5, 7, 8, 1, 2, 6, 1, 6, 5, &
                              2, 3, 7, 2, 7, 6, 3, 4, 8, 3, 8, 7, 4, 1, 5, 4, 5, 8], [3, 12]), 'box')
    call lib%add(s, id)
  end subroutine make_shapes

  !> Every value is a function of the gid, so any rank can check any body. gid 4 is the box.
  subroutine make_bodies(gids, b)
    integer(i8), intent(in) :: gids(:)
    type(bodies_t), intent(inout) :: b
    integer :: n
    n = size(gids)
    call b%allocate(max(n, 1))
    b%n_owned = n
    do i = 1, n
      call body_values(gids(i), b, i)
    end do
  end subroutine make_bodies

  subroutine body_values(gid, b, i)
    integer(i8), intent(in) :: gid
    type(bodies_t), intent(inout) :: b
    integer, intent(in) :: i
    real(dp) :: g
    g = real(gid, dp)
    b%gid(i) = gid
    b%shape_id(i) = merge(2, 1, gid == 4)
    b%group_id(i) = int(2 - mod(gid, 2_i8))
    b%fixed(i) = gid == 5
    b%mass(i) = g/3.0_dp
    b%inv_mass(i) = 3.0_dp/g
    if (gid == 5) b%inv_mass(i) = 0.0_dp
    do k = 1, 3
      b%inertia(k, i) = g*k/7.0_dp
      b%inv_inertia(k, i) = 7.0_dp/(g*k)
      b%a(k, i) = -g/k
      b%alpha(k, i) = g*k*1.0e-3_dp
    end do
    b%x(:, i) = [g, 2.0_dp*g, -g/3.0_dp]
    b%q(:, i) = [1.0_dp, 0.0_dp, 0.0_dp, 0.0_dp]
    b%v(:, i) = [0.1_dp*g, 0.0_dp, 0.0_dp]
    b%w(:, i) = [0.0_dp, 0.0_dp, g]
  end subroutine body_values

  logical function all_bodies_exact(b)
    type(bodies_t), intent(in) :: b
    type(bodies_t) :: expected
    integer :: j
    call expected%allocate(b%n_owned)
    do j = 1, b%n_owned
      call body_values(b%gid(j), expected, j)
    end do
    j = b%n_owned
    all_bodies_exact = all(b%shape_id(1:j) == expected%shape_id(1:j)) .and. &
                       all(b%group_id(1:j) == expected%group_id(1:j)) .and. &
                       all(b%fixed(1:j) .eqv. expected%fixed(1:j)) .and. &
                       all(b%mass(1:j) == expected%mass(1:j)) .and. all(b%inv_mass(1:j) == expected%inv_mass(1:j)) .and. &
                       all(b%inertia(:, 1:j) == expected%inertia(:, 1:j)) .and. &
                       all(b%inv_inertia(:, 1:j) == expected%inv_inertia(:, 1:j)) .and. &
                       all(b%x(:, 1:j) == expected%x(:, 1:j)) .and. all(b%q(:, 1:j) == expected%q(:, 1:j)) .and. &
                       all(b%v(:, 1:j) == expected%v(:, 1:j)) .and. all(b%w(:, 1:j) == expected%w(:, 1:j)) .and. &
                       all(b%a(:, 1:j) == expected%a(:, 1:j)) .and. all(b%alpha(:, 1:j) == expected%alpha(:, 1:j))
  end function all_bodies_exact

end program test_parallel_output
