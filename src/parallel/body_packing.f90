!> Bodies to and from one contiguous real(dp) buffer: what migration (owned rows to their
!> new owner) and the halo exchange (ghost rows to the neighbours) will send, one message
!> per neighbour and pass. MPI-free: parallel_env will send the buffer as doubles.
!>
!> Layout version 1 (every word a real(dp); integers are stored bit for bit with
!> transfer(), so they survive exactly as long as the words are only moved, never
!> computed with: MPI_DOUBLE_PRECISION transfers and array copies only move them):
!>
!>     header (4 words, integers):  layout version, bodies n, words per body w, extras e
!>     n records of w = 31 + e words, in the order of the rows packed:
!>        1 gid   2 shape_id   3 group_id   4 flags (bit 0 fixed, bit 1 asleep)   (integers)
!>        5 mass   6 inv_mass   7:9 inertia   10:12 inv_inertia   13:15 x   16:19 q
!>        20:22 v   23:25 w   26:28 a   29:31 alpha                           (reals)
!>        32:31+e  the caller's extra integers of the body (trajectory version, ...)
!>
!> A record is the whole row, so a migrated body is its row bitwise on the new owner. A
!> ghost needs less (id, shape, anchor, velocities, version): a shorter ghost record is a
!> later optimisation with its own layout version.
module body_packing
  use kinds, only: dp, i8
  use body_state, only: bodies_t
  use error_status, only: error_t, ERR_PARALLEL
  use string_utils, only: str
  implicit none
  private
  public :: PACK_LAYOUT_VERSION, PACK_HEADER_WORDS, BODY_WORDS
  public :: packed_words, pack_bodies, unpack_bodies, unpack_blocks, packed_count, pack_for_neighbour, PACKED_WORD_BYTES

  !> Bytes of one buffer word (the buffers are real(dp)).
  integer, parameter :: PACKED_WORD_BYTES = storage_size(1.0_dp)/8

  integer, parameter :: PACK_LAYOUT_VERSION = 1
  integer, parameter :: PACK_HEADER_WORDS = 4
  integer, parameter :: BODY_WORDS = 31      !< words of a record without extras

contains

  !> Buffer length for n bodies with n_extra extra integers each.
  pure integer function packed_words(n, n_extra)
    integer, intent(in) :: n, n_extra
    packed_words = PACK_HEADER_WORDS + n*(BODY_WORDS + n_extra)
  end function packed_words

  !> Bodies in a buffer, from its header (-1 if it is not one of ours).
  pure integer function packed_count(buffer)
    real(dp), intent(in) :: buffer(:)
    packed_count = -1
    if (size(buffer) < PACK_HEADER_WORDS) return
    if (as_int(buffer(1)) /= PACK_LAYOUT_VERSION) return
    packed_count = int(as_int(buffer(2)))
  end function packed_count

  !> The rows rows(:) of bodies (owned or ghost), in that order, into buffer (allocated to
  !> its exact length). extra(:, k): the caller's integers of row k, packed with it.
  subroutine pack_bodies(bodies, rows, buffer, extra, extra_of_rows)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: rows(:)
    real(dp), allocatable, intent(out) :: buffer(:)
    integer(i8), intent(in), optional :: extra(:, :)
    !> (instead of extra) extra_of_rows(:, k): the extras of body rows(k)
    integer(i8), intent(in), optional :: extra_of_rows(:, :)
    integer :: n_extra, w, k, i, o, flags
    n_extra = 0
    if (present(extra)) n_extra = size(extra, 1)
    if (present(extra_of_rows)) n_extra = size(extra_of_rows, 1)
    w = BODY_WORDS + n_extra
    allocate (buffer(packed_words(size(rows), n_extra)))
    buffer(1) = as_real(int(PACK_LAYOUT_VERSION, i8))
    buffer(2) = as_real(int(size(rows), i8))
    buffer(3) = as_real(int(w, i8))
    buffer(4) = as_real(int(n_extra, i8))
    do k = 1, size(rows)
      i = rows(k)
      o = PACK_HEADER_WORDS + (k - 1)*w
      flags = 0
      if (bodies%fixed(i)) flags = ibset(flags, 0)
      if (bodies%asleep(i)) flags = ibset(flags, 1)
      buffer(o + 1) = as_real(bodies%gid(i))
      buffer(o + 2) = as_real(int(bodies%shape_id(i), i8))
      buffer(o + 3) = as_real(int(bodies%group_id(i), i8))
      buffer(o + 4) = as_real(int(flags, i8))
      buffer(o + 5) = bodies%mass(i)
      buffer(o + 6) = bodies%inv_mass(i)
      buffer(o + 7:o + 9) = bodies%inertia(:, i)
      buffer(o + 10:o + 12) = bodies%inv_inertia(:, i)
      buffer(o + 13:o + 15) = bodies%x(:, i)
      buffer(o + 16:o + 19) = bodies%q(:, i)
      buffer(o + 20:o + 22) = bodies%v(:, i)
      buffer(o + 23:o + 25) = bodies%w(:, i)
      buffer(o + 26:o + 28) = bodies%a(:, i)
      buffer(o + 29:o + 31) = bodies%alpha(:, i)
      if (n_extra == 0) cycle
      if (present(extra_of_rows)) then
        buffer(o + 32:o + w) = as_reals(extra_of_rows(:, k))
      else
        buffer(o + 32:o + w) = as_reals(extra(:, i))
      end if
    end do
  end subroutine pack_bodies

  !> Every buffer of a concatenation of pack_bodies buffers (what an alltoallv of them
  !> receives) appended to bodies as owned rows, in order; extra(:, k), when present, the
  !> packed extra integers of the k-th body appended (every buffer with the same extras).
  !> A tail shorter than a header is ignored.
  subroutine unpack_blocks(buffer, bodies, err, extra)
    real(dp), intent(in) :: buffer(:)
    type(bodies_t), intent(inout) :: bodies
    type(error_t), intent(inout) :: err
    integer(i8), allocatable, intent(out), optional :: extra(:, :)
    integer(i8), allocatable :: got(:, :), grown(:, :)
    integer :: o, n_words
    o = 0
    do while (size(buffer) - o >= PACK_HEADER_WORDS)
      n_words = int(PACK_HEADER_WORDS + as_int(buffer(o + 2))*as_int(buffer(o + 3)))
      if (n_words < PACK_HEADER_WORDS .or. o + n_words > size(buffer)) then
        call err%set(ERR_PARALLEL, 'body buffers: a header at word '//str(o + 1)//' reaches past the '// &
                     str(size(buffer))//' words received')
        return
      end if
      if (.not. present(extra)) then
        call unpack_bodies(buffer(o + 1:o + n_words), bodies, .false., err)
      else
        call unpack_bodies(buffer(o + 1:o + n_words), bodies, .false., err, extra=got)
        if (err%ok()) then
          if (.not. allocated(extra)) then
            call move_alloc(got, extra)
          else
            allocate (grown(size(extra, 1), size(extra, 2) + size(got, 2)))
            grown(:, 1:size(extra, 2)) = extra
            grown(:, size(extra, 2) + 1:) = got
            call move_alloc(grown, extra)
          end if
        end if
      end if
      if (err%failed()) return
      o = o + n_words
    end do
    if (present(extra)) then
      if (.not. allocated(extra)) allocate (extra(0, 0))
    end if
  end subroutine unpack_blocks

  !> The bodies of a buffer appended to bodies as owned rows (before the ghosts, which move
  !> up) or as ghost rows (at the end), in buffer order. first: the row of the first one.
  !> extra(:, k): the packed extra integers of the k-th body unpacked.
  subroutine unpack_bodies(buffer, bodies, as_ghost, err, first, extra)
    real(dp), intent(in) :: buffer(:)
    type(bodies_t), intent(inout) :: bodies
    logical, intent(in) :: as_ghost
    type(error_t), intent(inout) :: err
    integer, intent(out), optional :: first
    integer(i8), allocatable, intent(out), optional :: extra(:, :)
    integer(i8) :: version, n8, w8, e8
    integer :: n, w, n_extra, k, j, o, flags, row1
    if (size(buffer) < PACK_HEADER_WORDS) then
      call err%set(ERR_PARALLEL, 'body buffer: '//str(size(buffer))//' words, shorter than its header')
      return
    end if
    version = as_int(buffer(1))
    n8 = as_int(buffer(2))
    w8 = as_int(buffer(3))
    e8 = as_int(buffer(4))
    if (version /= PACK_LAYOUT_VERSION) then
      call err%set(ERR_PARALLEL, 'body buffer: layout version '//str(version)//', this build reads '// &
                   str(PACK_LAYOUT_VERSION))
      return
    end if
    if (n8 < 0 .or. e8 < 0 .or. w8 /= BODY_WORDS + e8 .or. &
        int(size(buffer), i8) /= PACK_HEADER_WORDS + n8*w8) then
      call err%set(ERR_PARALLEL, 'body buffer: header says '//str(n8)//' bodies of '//str(w8)// &
                   ' words ('//str(e8)//' extras) but the buffer has '//str(size(buffer))//' words')
      return
    end if
    n = int(n8)
    w = int(w8)
    n_extra = int(e8)
    call bodies%open_rows(n, as_ghost, row1)
    if (present(first)) first = row1
    if (present(extra)) allocate (extra(n_extra, n))
    do k = 1, n
      j = row1 + k - 1
      o = PACK_HEADER_WORDS + (k - 1)*w
      bodies%gid(j) = as_int(buffer(o + 1))
      bodies%shape_id(j) = int(as_int(buffer(o + 2)))
      bodies%group_id(j) = int(as_int(buffer(o + 3)))
      flags = int(as_int(buffer(o + 4)))
      bodies%fixed(j) = btest(flags, 0)
      bodies%asleep(j) = btest(flags, 1)
      bodies%mass(j) = buffer(o + 5)
      bodies%inv_mass(j) = buffer(o + 6)
      bodies%inertia(:, j) = buffer(o + 7:o + 9)
      bodies%inv_inertia(:, j) = buffer(o + 10:o + 12)
      bodies%x(:, j) = buffer(o + 13:o + 15)
      bodies%q(:, j) = buffer(o + 16:o + 19)
      bodies%v(:, j) = buffer(o + 20:o + 22)
      bodies%w(:, j) = buffer(o + 23:o + 25)
      bodies%a(:, j) = buffer(o + 26:o + 28)
      bodies%alpha(:, j) = buffer(o + 29:o + 31)
      if (present(extra) .and. n_extra > 0) extra(:, k) = as_ints(buffer(o + 32:o + w))
    end do
  end subroutine unpack_bodies

  pure real(dp) function as_real(value)
    integer(i8), intent(in) :: value
    as_real = transfer(value, 1.0_dp)
  end function as_real

  pure integer(i8) function as_int(word)
    real(dp), intent(in) :: word
    as_int = transfer(word, 1_i8)
  end function as_int

  pure function as_reals(values) result(words)
    integer(i8), intent(in) :: values(:)
    real(dp) :: words(size(values))
    words = transfer(values, words)
  end function as_reals

  pure function as_ints(words) result(values)
    real(dp), intent(in) :: words(:)
    integer(i8) :: values(size(words))
    values = transfer(words, values)
  end function as_ints

  !> The buffer for one neighbour of a staged exchange (halo or migration): the rows packed
  !> with their extras (a header alone when there are none, so every message can be
  !> checked), or nothing without a neighbour (neighbour < 0: MPI_PROC_NULL sends nothing).
  !> messages, n_sent, bytes: the sender's counts, added to.
  subroutine pack_for_neighbour(bodies, rows, extra, n_extra, neighbour, buffer, messages, n_sent, bytes, by_position)
    type(bodies_t), intent(in) :: bodies
    integer, intent(in) :: rows(:)
    integer(i8), intent(in) :: extra(:, :)
    integer, intent(in) :: n_extra, neighbour
    real(dp), allocatable, intent(out) :: buffer(:)
    integer(i8), intent(inout) :: messages, n_sent, bytes
    !> extra(:, k) is the extras of rows(k) (pack_bodies' extra_of_rows), not of row k
    logical, intent(in), optional :: by_position
    logical :: positional
    positional = .false.
    if (present(by_position)) positional = by_position
    if (neighbour < 0) then
      allocate (buffer(0))
      return
    end if
    if (n_extra > 0 .and. positional) then
      call pack_bodies(bodies, rows, buffer, extra_of_rows=extra)
    else if (n_extra > 0) then
      call pack_bodies(bodies, rows, buffer, extra)
    else
      call pack_bodies(bodies, rows, buffer)
    end if
    messages = messages + 1
    n_sent = n_sent + size(rows)
    bytes = bytes + int(size(buffer), i8)*PACKED_WORD_BYTES
  end subroutine pack_for_neighbour

end module body_packing
