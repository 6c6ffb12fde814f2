!> The only module that calls MPI. A serial build (RICOCHET_USE_MPI off) compiles the same
!> interface with one rank, so the physics never branches on whether MPI is there.
!>
!> Besides the world communicator (collectives, output) a run may hold a Cartesian one for
!> the domain decomposition (cart_create): made with periods false and reorder false, so
!> its ranks are the world ranks and its numbering is domain_t's (row-major, the last
!> coordinate fastest). exchange_faces is the one point-to-point operation: the halo
!> exchange's pass along one axis, a buffer to and from each face neighbour.
module parallel_env
#ifdef RICOCHET_USE_MPI
  use mpi_f08, only: MPI_Comm, MPI_COMM_WORLD, MPI_Init, MPI_Finalize, MPI_Initialized, &
                     MPI_Finalized, MPI_Comm_rank, MPI_Comm_size, MPI_Allreduce, MPI_Exscan, &
                     MPI_Bcast, MPI_Barrier, MPI_Abort, MPI_Wtime, MPI_SUM, MPI_MAX, MPI_MIN, &
                     MPI_DOUBLE_PRECISION, MPI_INTEGER, MPI_INTEGER8, MPI_LOGICAL, MPI_LOR, &
                     MPI_CHARACTER, MPI_IN_PLACE, MPI_Cart_create, MPI_Cart_shift, MPI_Comm_free, &
                     MPI_Sendrecv, MPI_Status, MPI_PROC_NULL, MPI_SUCCESS, MPI_Alltoall, MPI_Alltoallv, &
                     MPI_Allgather, MPI_Allgatherv, MPI_Datatype, MPI_Type_contiguous, MPI_Type_commit, &
                     MPI_Type_free, MPI_BYTE, MPI_DATATYPE_NULL, operator(/=)
#endif
  use kinds, only: dp, i8
  use error_status, only: error_t, ERR_INTERNAL, ERR_PARALLEL
  use string_utils, only: str
  use exact_sum, only: exact_sum_t, EXACT_SUM_WORDS
  implicit none
  private
  public :: parallel_t

  !> A communicator and this rank's place in it.
  type :: parallel_t
#ifdef RICOCHET_USE_MPI
    type(MPI_Comm) :: comm
    type(MPI_Comm) :: cart          !< the Cartesian communicator (valid when has_cart)
#endif
    integer :: rank = 0
    integer :: n_ranks = 1
    logical :: owns_mpi = .false.   !< this object initialised MPI and must finalise it
    logical :: has_cart = .false.   !< cart_create has made the Cartesian communicator
    integer :: cart_dims(3) = 1     !< its ranks along x, y, z
    integer :: cart_rank = 0        !< this rank in it (= rank: reorder is false)
  contains
    procedure :: init => parallel_init
    procedure :: free => parallel_free
    procedure :: is_root => parallel_is_root
    procedure :: barrier => parallel_barrier
    procedure :: abort => parallel_abort
    procedure :: wtime => parallel_wtime
    procedure :: comm_handle => parallel_comm_handle
    procedure :: cart_create => parallel_cart_create
    procedure :: cart_free => parallel_cart_free
    procedure :: exchange_faces => parallel_exchange_faces
    procedure :: alltoallv => parallel_alltoallv
    procedure :: allgather_lines => parallel_allgather_lines
    procedure :: allgather_blocks_in_place => parallel_allgather_blocks_in_place
    generic :: sum => sum_dp, sum_int, sum_int8
    generic :: sum_inplace => sum_dp_array, sum_exact_array, sum_exact_one
    generic :: max => max_dp, max_int
    generic :: min => min_dp, min_int8
    generic :: any => any_logical
    generic :: exscan => exscan_int8
    generic :: bcast => bcast_string, bcast_int, bcast_dp_array
    procedure, private :: sum_dp, sum_dp_array, sum_exact_array, sum_exact_one, sum_int, sum_int8, max_dp, max_int, min_dp, min_int8, &
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
#endif
    call self%cart_free()
#ifdef RICOCHET_USE_MPI
    if (self%owns_mpi) then
      call MPI_Finalized(done)
      if (.not. done) call MPI_Finalize()
      self%owns_mpi = .false.
    end if
#endif
  end subroutine parallel_free

  !> The Cartesian communicator of a dims(1) x dims(2) x dims(3) rank grid over all ranks
  !> (replacing one made before). periods false: the domain has walls, not wrap-around;
  !> reorder false: the Cartesian rank stays the world rank, so domain_t (built from it)
  !> and the output's rank order agree. The world communicator stays for everything else.
  subroutine parallel_cart_create(self, dims, err)
    class(parallel_t), intent(inout) :: self
    integer, intent(in) :: dims(3)
    type(error_t), intent(inout) :: err
#ifdef RICOCHET_USE_MPI
    integer :: ierror
#endif
    if (any(dims < 1) .or. product(int(dims, i8)) /= int(self%n_ranks, i8)) then
      call err%set(ERR_PARALLEL, 'parallel: a '//str(dims(1))//' x '//str(dims(2))//' x '//str(dims(3))// &
                   ' rank grid does not fit '//str(self%n_ranks)//' rank(s)')
      return
    end if
    call self%cart_free()
#ifdef RICOCHET_USE_MPI
    call MPI_Cart_create(self%comm, 3, dims, [.false., .false., .false.], .false., self%cart, ierror)
    if (ierror /= MPI_SUCCESS) then
      call err%set(ERR_PARALLEL, 'parallel: MPI_Cart_create failed (error '//str(ierror)//')')
      return
    end if
    call MPI_Comm_rank(self%cart, self%cart_rank)
#else
    self%cart_rank = 0
#endif
    self%cart_dims = dims
    self%has_cart = .true.
  end subroutine parallel_cart_create

  !> Drops the Cartesian communicator, if any (collective over its ranks).
  subroutine parallel_cart_free(self)
    class(parallel_t), intent(inout) :: self
#ifdef RICOCHET_USE_MPI
    logical :: done
    if (self%has_cart) then
      ! after MPI_Finalize (someone else's) the handle is gone with the library
      call MPI_Finalized(done)
      if (.not. done) call MPI_Comm_free(self%cart)
    end if
#endif
    self%has_cart = .false.
    self%cart_dims = 1
    self%cart_rank = self%rank
  end subroutine parallel_cart_free

  !> One pass of the halo exchange along axis (1..3) of the Cartesian communicator:
  !> send_minus goes to the face neighbour on the minus side, minus_rank, and send_plus to
  !> plus_rank; recv_minus and recv_plus are what those neighbours sent this rank. A
  !> neighbour rank < 0 (domain_t's NO_RANK) is none: MPI_PROC_NULL, nothing sent, an empty
  !> buffer received. Lengths go first (one integer each way), so the receiver sizes its
  !> buffer exactly; then the payloads. Each direction is one MPI_Sendrecv, so a row of
  !> ranks shifts in step and no ordering of sends can deadlock. The neighbours are checked
  !> against MPI_Cart_shift: domain_t and the communicator must number the ranks alike (on
  !> a mismatch this rank sends empty buffers to the communicator's neighbours and fails).
  !> Collective over the ranks of the communicator (every one calls it for the same axis).
  subroutine parallel_exchange_faces(self, axis, minus_rank, plus_rank, send_minus, send_plus, &
                                     recv_minus, recv_plus, err)
    class(parallel_t), intent(in) :: self
    integer, intent(in) :: axis
    integer, intent(in) :: minus_rank, plus_rank
    real(dp), intent(in) :: send_minus(:), send_plus(:)
    real(dp), allocatable, intent(out) :: recv_minus(:), recv_plus(:)
    type(error_t), intent(inout) :: err
#ifdef RICOCHET_USE_MPI
    ! tags: lengths and payloads, towards plus and towards minus, kept apart so that a
    ! rank with the same rank on both sides (a periodic axis of two ranks, should the
    ! grid ever wrap) still pairs them right
    integer, parameter :: TAG_LENGTH_UP = 101, TAG_LENGTH_DOWN = 102, TAG_DATA_UP = 103, &
                          TAG_DATA_DOWN = 104
    integer :: minus, plus, shift_minus, shift_plus, n_send_minus, n_send_plus, n_from_minus, &
               n_from_plus, ierror(4)
    logical :: mismatch
    type(MPI_Status) :: status
#endif
    allocate (recv_minus(0), recv_plus(0))
    if (.not. self%has_cart) then
      call err%set(ERR_INTERNAL, 'parallel: exchange_faces before cart_create')
      return
    end if
    if (axis < 1 .or. axis > 3) then
      call err%set(ERR_INTERNAL, 'parallel: exchange_faces along axis '//str(axis)//', not 1..3')
      return
    end if
#ifdef RICOCHET_USE_MPI
    minus = MPI_PROC_NULL
    plus = MPI_PROC_NULL
    if (minus_rank >= 0) minus = minus_rank
    if (plus_rank >= 0) plus = plus_rank
    call MPI_Cart_shift(self%cart, axis - 1, 1, shift_minus, shift_plus)
    mismatch = shift_minus /= minus .or. shift_plus /= plus
    if (mismatch) then
      ! a bug in the caller; still trade (empty) messages with the communicator's own
      ! neighbours, who expect them: an error is reported, nobody waits forever
      call err%set(ERR_INTERNAL, 'parallel: face neighbours '//str(minus_rank)//' and '//str(plus_rank)// &
                   ' along axis '//str(axis)//' are not the Cartesian communicator''s')
    end if
    n_send_minus = size(send_minus)
    n_send_plus = size(send_plus)
    if (mismatch) then
      n_send_minus = 0
      n_send_plus = 0
    end if
    n_from_minus = 0          ! MPI_PROC_NULL leaves the receive buffer as it is
    n_from_plus = 0
    call MPI_Sendrecv(n_send_plus, 1, MPI_INTEGER, shift_plus, TAG_LENGTH_UP, &
                      n_from_minus, 1, MPI_INTEGER, shift_minus, TAG_LENGTH_UP, self%cart, status, ierror(1))
    call MPI_Sendrecv(n_send_minus, 1, MPI_INTEGER, shift_minus, TAG_LENGTH_DOWN, &
                      n_from_plus, 1, MPI_INTEGER, shift_plus, TAG_LENGTH_DOWN, self%cart, status, ierror(2))
    deallocate (recv_minus, recv_plus)
    allocate (recv_minus(max(n_from_minus, 0)), recv_plus(max(n_from_plus, 0)))
    call MPI_Sendrecv(send_plus, n_send_plus, MPI_DOUBLE_PRECISION, shift_plus, TAG_DATA_UP, &
                      recv_minus, size(recv_minus), MPI_DOUBLE_PRECISION, shift_minus, TAG_DATA_UP, &
                      self%cart, status, ierror(3))
    call MPI_Sendrecv(send_minus, n_send_minus, MPI_DOUBLE_PRECISION, shift_minus, TAG_DATA_DOWN, &
                      recv_plus, size(recv_plus), MPI_DOUBLE_PRECISION, shift_plus, TAG_DATA_DOWN, &
                      self%cart, status, ierror(4))
    if (mismatch) then
      deallocate (recv_minus, recv_plus)
      allocate (recv_minus(0), recv_plus(0))
      return
    end if
    if (any(ierror /= MPI_SUCCESS)) call err%set(ERR_PARALLEL, 'parallel: the halo exchange along axis '// &
                                                 str(axis)//' failed (MPI error '//str(maxval(ierror))//')')
#else
    ! one rank: no neighbours, so nothing to send and nothing arrives
    if (minus_rank >= 0 .or. plus_rank >= 0) then
      call err%set(ERR_INTERNAL, 'parallel: a face neighbour along axis '//str(axis)// &
                   ' in a build without MPI')
      return
    end if
    if (.false.) recv_minus = [send_minus, send_plus]
#endif
  end subroutine parallel_exchange_faces

  !> Every rank sends send(first(r)+1 : first(r)+counts(r)) to rank r (first: the exclusive
  !> prefix sum of counts, so send holds the parts in rank order) and receives, in rank
  !> order, what each sent it into recv: one MPI_Alltoall of the counts, one MPI_Alltoallv of
  !> the words. Used to bring rows to the rank of their global-id block (output, checkpoints),
  !> where the destinations are any ranks, not only neighbours.
  subroutine parallel_alltoallv(self, send, counts, recv, err)
    class(parallel_t), intent(in) :: self
    real(dp), intent(in) :: send(:)
    integer, intent(in) :: counts(0:)            !< words for each rank 0..n_ranks-1
    real(dp), allocatable, intent(out) :: recv(:)
    type(error_t), intent(inout) :: err
#ifdef RICOCHET_USE_MPI
    integer, allocatable :: recv_counts(:), send_first(:), recv_first(:)
    integer :: ierror
#endif
    if (size(counts) /= self%n_ranks .or. sum(int(counts, i8)) /= int(size(send), i8)) then
      call err%set(ERR_INTERNAL, 'parallel: alltoallv with '//str(size(counts))//' counts summing to '// &
                   str(sum(int(counts, i8)))//' for '//str(self%n_ranks)//' ranks and '//str(size(send))//' words')
      allocate (recv(0))
      return
    end if
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) then
      allocate (recv_counts(0:self%n_ranks - 1), send_first(0:self%n_ranks - 1), recv_first(0:self%n_ranks - 1))
      call MPI_Alltoall(counts, 1, MPI_INTEGER, recv_counts, 1, MPI_INTEGER, self%comm, ierror)
      send_first = exclusive_prefix(counts)
      recv_first = exclusive_prefix(recv_counts)
      allocate (recv(sum(recv_counts)))
      if (ierror == MPI_SUCCESS) call MPI_Alltoallv(send, counts, send_first, MPI_DOUBLE_PRECISION, recv, &
                                                    recv_counts, recv_first, MPI_DOUBLE_PRECISION, self%comm, ierror)
      if (ierror /= MPI_SUCCESS) call err%set(ERR_PARALLEL, 'parallel: alltoallv failed (MPI error '// &
                                              str(ierror)//')')
      return
    end if
#endif
    recv = send
  end subroutine parallel_alltoallv

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

  !> Exact sums over ranks (exact_sum): every rank ends with the same accumulators, the
  !> exact sum of all ranks' terms, so their value() is bitwise the same for any split of
  !> the terms over any number of ranks. The limbs are integers and the reduction is an
  !> integer MPI_SUM (associative, commutative: the reduction order cannot matter);
  !> normalised limbs are below 2^32, so fewer than 2^31 ranks (any communicator) cannot
  !> overflow int64. One MPI_Allreduce of EXACT_SUM_WORDS integers per accumulator.
  subroutine sum_exact_array(self, sums)
    class(parallel_t), intent(in) :: self
    type(exact_sum_t), intent(inout) :: sums(:)
#ifdef RICOCHET_USE_MPI
    integer(i8), allocatable :: words(:, :)
    integer :: k
    if (self%n_ranks == 1 .or. size(sums) == 0) return
    allocate (words(EXACT_SUM_WORDS, size(sums)))
    do k = 1, size(sums)
      words(:, k) = sums(k)%words()
    end do
    call MPI_Allreduce(MPI_IN_PLACE, words, size(words), MPI_INTEGER8, MPI_SUM, self%comm)
    do k = 1, size(sums)
      call sums(k)%set_words(words(:, k), self%n_ranks)
    end do
#else
    if (.false.) call sums(1)%reset()
#endif
  end subroutine sum_exact_array

  subroutine sum_exact_one(self, sum)
    class(parallel_t), intent(in) :: self
    type(exact_sum_t), intent(inout) :: sum
    type(exact_sum_t) :: one(1)
    one(1) = sum
    call self%sum_exact_array(one)
    sum = one(1)
  end subroutine sum_exact_one

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

  !> The smallest value over every rank: the first item (in an order all ranks share) that
  !> some rank found, when each rank searched its own share of the items.
  integer(i8) function min_int8(self, value)
    class(parallel_t), intent(in) :: self
    integer(i8), intent(in) :: value
    min_int8 = value
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) call MPI_Allreduce(value, min_int8, 1, MPI_INTEGER8, MPI_MIN, self%comm)
#endif
  end function min_int8

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

  !> Every rank's lines (trailing blanks not kept), rank 0's first, in each rank's order,
  !> on every rank: all as wide as the longest. Collective.
  subroutine parallel_allgather_lines(self, mine, all)
    class(parallel_t), intent(in) :: self
    character(len=*), intent(in) :: mine(:)
    character(len=:), allocatable, intent(out) :: all(:)
    integer, allocatable :: lengths(:), all_lengths(:), n_lines(:), n_chars(:), line_at(:), char_at(:)
    character(len=:), allocatable :: flat, all_flat
    integer :: k, o, width, total
    allocate (lengths(size(mine)))
    do k = 1, size(mine)
      lengths(k) = len_trim(mine(k))
    end do
    allocate (character(len=sum(lengths)) :: flat)
    o = 0
    do k = 1, size(mine)
      flat(o + 1:o + lengths(k)) = mine(k)(1:lengths(k))
      o = o + lengths(k)
    end do
    allocate (n_lines(0:self%n_ranks - 1), n_chars(0:self%n_ranks - 1))
    n_lines = size(mine)
    n_chars = len(flat)
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) then
      call MPI_Allgather(size(mine), 1, MPI_INTEGER, n_lines, 1, MPI_INTEGER, self%comm)
      call MPI_Allgather(len(flat), 1, MPI_INTEGER, n_chars, 1, MPI_INTEGER, self%comm)
    end if
#endif
    allocate (line_at(0:self%n_ranks - 1), char_at(0:self%n_ranks - 1))
    line_at = exclusive_prefix(n_lines)
    char_at = exclusive_prefix(n_chars)
    total = sum(n_chars)
    allocate (all_lengths(sum(n_lines)))
    allocate (character(len=total) :: all_flat)
    if (self%n_ranks == 1) then
      all_lengths = lengths
      all_flat = flat
    end if
#ifdef RICOCHET_USE_MPI
    if (self%n_ranks > 1) then
      call MPI_Allgatherv(lengths, size(lengths), MPI_INTEGER, all_lengths, n_lines, line_at, MPI_INTEGER, self%comm)
      call MPI_Allgatherv(flat, len(flat), MPI_CHARACTER, all_flat, n_chars, char_at, MPI_CHARACTER, self%comm)
    end if
#endif
    width = 1
    if (size(all_lengths) > 0) width = max(1, maxval(all_lengths))
    allocate (character(len=width) :: all(size(all_lengths)))
    o = 0
    do k = 1, size(all_lengths)
      all(k) = all_flat(o + 1:o + all_lengths(k))
      o = o + all_lengths(k)
    end do
  end subroutine parallel_allgather_lines

  !> Every rank holds records(:) (contiguous, record_bytes bytes each) and has filled its
  !> own block of n_mine records, the blocks in rank order one after another; afterwards
  !> every rank holds every block, bit for bit (records travel as bytes: a type without
  !> allocatable or pointer components). In place: no copy of the records on either side,
  !> where gathering them as 64-bit words through a buffer took four copies (the deck's
  !> &body specs, 150 MB at 100,000 bodies). Counted in records (an MPI type of one), so
  !> that 10^7 records of a kilobyte stay within MPI's int counts. Collective.
  subroutine parallel_allgather_blocks_in_place(self, records, record_bytes, n_mine)
    class(parallel_t), intent(in) :: self
    type(*), intent(inout) :: records(..)
    integer, intent(in) :: record_bytes, n_mine
#ifdef RICOCHET_USE_MPI
    integer, allocatable :: counts(:), first(:)
    type(MPI_Datatype) :: record
    if (self%n_ranks == 1) return
    allocate (counts(0:self%n_ranks - 1))
    call MPI_Allgather(n_mine, 1, MPI_INTEGER, counts, 1, MPI_INTEGER, self%comm)
    first = exclusive_prefix(counts)
    call MPI_Type_contiguous(record_bytes, MPI_BYTE, record)
    call MPI_Type_commit(record)
    call MPI_Allgatherv(MPI_IN_PLACE, 0, MPI_DATATYPE_NULL, records, counts, first, record, self%comm)
    call MPI_Type_free(record)
#else
    if (.false.) print *, rank(records), record_bytes, n_mine, self%n_ranks
#endif
  end subroutine parallel_allgather_blocks_in_place

  !> Where each rank's part starts in a concatenation of parts of counts(:) items (0-based
  !> displacements, as MPI's v-collectives take them).
  pure function exclusive_prefix(counts) result(first)
    integer, intent(in) :: counts(:)
    integer :: first(size(counts))
    integer :: r
    if (size(counts) == 0) return
    first(1) = 0
    do r = 2, size(counts)
      first(r) = first(r - 1) + counts(r - 1)
    end do
  end function exclusive_prefix

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
