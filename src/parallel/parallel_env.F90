!> The only module that calls MPI. A serial build (RICOCHET_USE_MPI off) compiles the same
!> interface with one rank, so the physics never branches on whether MPI is there.
module parallel_env
#ifdef RICOCHET_USE_MPI
  use mpi_f08, only: MPI_Comm, MPI_COMM_WORLD, MPI_Init, MPI_Finalize, MPI_Initialized, &
                     MPI_Finalized, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_Exscan, &
                     MPI_Bcast, MPI_Barrier, MPI_Abort, MPI_Wtime, MPI_SUM, MPI_MAX, MPI_MIN, &
                     MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_INTEGER8, MPI_LOGICAL, MPI_LOR, &
                     MPI_CHARACTER, MPI_IN_PLACE
#endif
  use kinds, only: dp, i8
  implicit none
  private
  public :: parallel_t

  !> A communicator and this rank's place in it.
  type :: parallel_t
#ifdef RICOCHET_USE_MPI
    type(MPI_Comm) :: comm
#endif
    integer :: rank = 0
    integer :: n_ranks = 1
    logical :: owns_mpi = .false.   !< this object initialised MPI and must finalise it
  contains
    procedure :: init => parallel_init
    procedure :: free => parallel_free
    procedure :: is_root => parallel_is_root
    procedure :: barrier => parallel_barrier
    procedure :: abort => parallel_abort
    procedure :: wtime => parallel_wtime
    procedure :: comm_handle => parallel_comm_handle
    generic :: sum => sum_dp, sum_int, sum_int8
    generic :: sum_inplace => sum_dp_array
    generic :: max => max_dp, max_int
    generic :: min => min_dp
    generic :: any => any_logical
    generic :: exscan => exscan_int8
    generic :: bcast => bcast_string, bcast_int, bcast_dp_array
    procedure, private :: sum_dp, sum_dp_array, sum_int, sum_int8, max_dp, max_int, min_dp, &
                          any_logical, exscan_int8, bcast_string, bcast_int, bcast_dp_array
  end type parallel_t

contains

  subroutine parallel_init(self)
    class(parallel_t), intent(inout) :: self
#ifdef RICOCHET_USE_MPI
    logical :: already
    call MPI_Initialized(already)
    if (.not. already) then
      call MPI_Init()
      self%owns_mpi = .true.
    end if
    self%comm = MPI_COMM_WORLD
    call MPI_Comm_rank(self%comm, self%rank)
    call MPI_Comm_size(self%comm, self%n_ranks)
#else
    self%rank = 0
    self%n_ranks = 1
#endif
  end subroutine parallel_init

  subroutine parallel_free(self)
    class(parallel_t), intent(inout) :: self
#ifdef RICOCHET_USE_MPI
    logical :: done
    if (self%owns_mpi) then
      call MPI_Finalized(done)
      if (.not. done) call MPI_Finalize()
      self%owns_mpi = .false.
    end if
#endif
  end subroutine parallel_free

  pure logical function parallel_is_root(self)
    class(parallel_t), intent(in) :: self
    parallel_is_root = self%rank == 0
  end function parallel_is_root

  !> Integer handle of the communicator for libraries with integer-handle APIs (HDF5 1.10).
  integer function parallel_comm_handle(self)
    class(parallel_t), intent(in) :: self
#ifdef RICOCHET_USE_MPI
    parallel_comm_handle = self%comm%MPI_VAL
#else
    parallel_comm_handle = 0
#endif
  end function parallel_comm_handle

  subroutine parallel_barrier(self)
    class(parallel_t), intent(in) :: self
#ifdef RICOCHET_USE_MPI
    call MPI_Barrier(self%comm)
#endif
  end subroutine parallel_barrier

  !> The one collective abort: used by the driver only, after printing its error line.
  subroutine parallel_abort(self, code)
    class(parallel_t), intent(in) :: self
    integer, intent(in) :: code
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Abort(self%comm, code)
#endif
    error stop code
  end subroutine parallel_abort

  real(dp) function parallel_wtime(self)
    class(parallel_t), intent(in) :: self
#ifdef RICOCHET_USE_MPI
    parallel_wtime = MPI_Wtime()
#else
    integer(i8) :: count, rate
    call system_clock(count, rate)
    parallel_wtime = real(count, dp)/real(rate, dp)
#endif
  end function parallel_wtime

  real(dp) function sum_dp(self, value)
    class(parallel_t), intent(in) :: self
    real(dp), intent(in) :: value
    sum_dp = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, sum_dp, 1, MPI_DOUBLE_PRECISION, MPI_SUM, self%comm)
#endif
  end function sum_dp

  subroutine sum_dp_array(self, values)
    class(parallel_t), intent(in) :: self
    real(dp), intent(inout) :: values(:)
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(MPI_IN_PLACE, values, size(values), MPI_DOUBLE_PRECISION, &
                                             MPI_SUM, self%comm)
#endif
  end subroutine sum_dp_array

  integer function sum_int(self, value)
    class(parallel_t), intent(in) :: self
    integer, intent(in) :: value
    sum_int = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, sum_int, 1, MPI_INTEGER, MPI_SUM, self%comm)
#endif
  end function sum_int

  integer(i8) function sum_int8(self, value)
    class(parallel_t), intent(in) :: self
    integer(i8), intent(in) :: value
    sum_int8 = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, sum_int8, 1, MPI_INTEGER8, MPI_SUM, self%comm)
#endif
  end function sum_int8

  real(dp) function max_dp(self, value)
    class(parallel_t), intent(in) :: self
    real(dp), intent(in) :: value
    max_dp = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, max_dp, 1, MPI_DOUBLE_PRECISION, MPI_MAX, self%comm)
#endif
  end function max_dp

  integer function max_int(self, value)
    class(parallel_t), intent(in) :: self
    integer, intent(in) :: value
    max_int = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, max_int, 1, MPI_INTEGER, MPI_MAX, self%comm)
#endif
  end function max_int

  real(dp) function min_dp(self, value)
    class(parallel_t), intent(in) :: self
    real(dp), intent(in) :: value
    min_dp = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, min_dp, 1, MPI_DOUBLE_PRECISION, MPI_MIN, self%comm)
#endif
  end function min_dp

  logical function any_logical(self, value)
    class(parallel_t), intent(in) :: self
    logical, intent(in) :: value
    any_logical = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, any_logical, 1, MPI_LOGICAL, MPI_LOR, self%comm)
#endif
  end function any_logical

  !> Exclusive prefix sum over ranks (0 on rank 0): offsets of this rank's rows in a file.
  integer(i8) function exscan_int8(self, value)
    class(parallel_t), intent(in) :: self
    integer(i8), intent(in) :: value
    exscan_int8 = 0
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) then
      call MPI_Exscan(value, exscan_int8, 1, MPI_INTEGER8, MPI_SUM, self%comm)
      if (self%rank == 0) exscan_int8 = 0
    end if
#else
    if (.false.) exscan_int8 = value
#endif
  end function exscan_int8

  subroutine bcast_string(self, text, root)
    class(parallel_t), intent(in) :: self
    character(len=:), allocatable, intent(inout) :: text
    integer, intent(in) :: root
#ifdef RICOCHET_USE_MPI
    integer :: length
    if (self%n_ranks == 1) return
    length = 0
    if (self%rank == root) length = len(text)
    call MPI_Bcast(length, 1, MPI_INTEGER, root, self%comm)
    if (self%rank /= root) then
      if (allocated(text)) deallocate (text)
      allocate (character(len=length) :: text)
    end if
    if (length > 0) call MPI_Bcast(text, length, MPI_CHARACTER, root, self%comm)
#else
    if (.false.) text = text(1:root)
#endif
  end subroutine bcast_string

  subroutine bcast_int(self, value, root)
    class(parallel_t), intent(in) :: self
    integer, intent(inout) :: value
    integer, intent(in) :: root
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Bcast(value, 1, MPI_INTEGER, root, self%comm)
#else
    if (.false.) value = root
#endif
  end subroutine bcast_int

  subroutine bcast_dp_array(self, values, root)
    class(parallel_t), intent(in) :: self
    real(dp), intent(inout) :: values(:)
    integer, intent(in) :: root
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Bcast(values, size(values), MPI_DOUBLE_PRECISION, root, self%comm)
#else
    if (.false.) values = real(root, dp)
#endif
  end subroutine bcast_dp_array

end module parallel_env
