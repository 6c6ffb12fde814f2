!> Stand-in for src/io/hdf5/checkpoint_io.f90 in builds without HDF5: same interface,
!> writing and reading fail with ERR_IO (check_checkpoint_matches works: it needs no HDF5).
module checkpoint_io
  use error_status, only: error_t, ERR_IO
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use checkpoint_meta, only: checkpoint_meta_t, check_checkpoint_matches
  implicit none
  private
  public :: write_checkpoint, read_checkpoint, check_checkpoint_matches, checkpoint_meta_t

  character(len=*), parameter :: no_hdf5 = 'checkpoints: ricochet was built without HDF5 '// &
                                           '(configure with -DRICOCHET_USE_HDF5=ON)'

contains

  ! The conditions below only touch every argument (no unused-argument warnings); they
  ! are always true.

  subroutine write_checkpoint(par, path, meta, bodies, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    type(checkpoint_meta_t), intent(in) :: meta
    type(bodies_t), intent(in) :: bodies
    type(error_t), intent(inout) :: err
    if (par%rank >= 0 .or. len(path) > 0 .or. meta%n_frames > 0 .or. bodies%n_owned > 0) &
      call err%set(ERR_IO, no_hdf5)
  end subroutine write_checkpoint

  subroutine read_checkpoint(par, path, meta, bodies, err)
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: path
    type(checkpoint_meta_t), intent(out) :: meta
    type(bodies_t), intent(inout) :: bodies
    type(error_t), intent(inout) :: err
    if (par%rank >= 0 .or. len(path) > 0 .or. meta%n_frames > 0 .or. bodies%n_owned > 0) &
      call err%set(ERR_IO, no_hdf5)
  end subroutine read_checkpoint

end module checkpoint_io
