!> Stand-in for src/io/hdf5/frame_writer.f90 in builds without HDF5: same interface, every
!> call fails with ERR_IO so a deck asking for output says why instead of writing nothing.
module frame_writer
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_IO
  use parallel_env, only: parallel_t
  use body_state, only: bodies_t
  use shape, only: shape_library_t
  implicit none
  private
  public :: frame_writer_t, frame_format, frame_version, frame_file_name

  character(len=*), parameter :: frame_format = 'ricochet-frame'
  integer, parameter :: frame_version = 1
  character(len=*), parameter :: no_hdf5 = 'frame output: ricochet was built without HDF5 '// &
                                           '(configure with -DRICOCHET_USE_HDF5=ON)'

  type :: frame_writer_t
    character(len=:), allocatable :: dir
    integer :: n_frames = 0
    real(dp), allocatable :: frame_times(:)
    integer(i8), allocatable :: frame_sizes(:, :)
    integer :: block_frames = 32
    integer :: n_blocks_written = 0
  contains

  ! The conditions below only touch every argument (no unused-argument warnings); they
  ! are always true.
    procedure :: init => frame_init
    procedure :: write => frame_write
    procedure :: restore => frame_restore
    procedure :: free => frame_free
  end type frame_writer_t

contains

  pure function frame_file_name(index) result(name)
    integer, intent(in) :: index
    character(len=:), allocatable :: name
    character(len=32) :: buffer
    write (buffer, '(a,i6.6,a)') 'frames/frame_', index, '.h5'
    name = trim(buffer)
  end function frame_file_name

  subroutine frame_init(self, par, dir, err)
    class(frame_writer_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    character(len=*), intent(in) :: dir
    type(error_t), intent(inout) :: err
    self%dir = dir
    if (par%rank >= 0) call err%set(ERR_IO, no_hdf5)
  end subroutine frame_init

  subroutine frame_restore(self, n_frames, frame_times)
    class(frame_writer_t), intent(inout) :: self
    integer, intent(in) :: n_frames
    real(dp), intent(in) :: frame_times(:)
    self%n_frames = max(0, min(n_frames, size(frame_times)))
    self%frame_times = frame_times(1:self%n_frames)
  end subroutine frame_restore

  subroutine frame_write(self, par, time, bodies, shapes, group_names, err)
    class(frame_writer_t), intent(inout) :: self
    type(parallel_t), intent(in) :: par
    real(dp), intent(in) :: time
    type(bodies_t), intent(in) :: bodies
    type(shape_library_t), intent(in) :: shapes
    character(len=*), intent(in) :: group_names(:)
    type(error_t), intent(inout) :: err
    if (par%rank >= 0 .or. time > 0 .or. bodies%n_owned > 0 .or. shapes%n_shapes > 0 .or. &
        size(group_names) > 0 .or. self%n_frames > 0) call err%set(ERR_IO, no_hdf5)
  end subroutine frame_write

  subroutine frame_free(self)
    class(frame_writer_t), intent(inout) :: self
    self%n_frames = 0
  end subroutine frame_free

end module frame_writer
