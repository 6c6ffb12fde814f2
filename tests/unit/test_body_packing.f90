!> body_packing: selected rows (owned and ghost, any order) packed and unpacked into other
!> bodies as owned rows (before that rank's ghosts) and as ghosts (at the end) are their
!> rows bit for bit, -0.0, a subnormal and huge included, and so are the extra integers
!> (-1 and huge(int64) too, whose bit patterns are NaNs as doubles: words are only moved);
!> the buffer has the documented length and header; an empty selection is a valid buffer;
!> a foreign version and a truncated buffer are errors that leave the bodies alone.
program test_body_packing
  use kinds, only: dp, i8
  use body_state, only: bodies_t
  use error_status, only: error_t
  use body_packing, only: pack_bodies, unpack_bodies, packed_words, packed_count, PACK_LAYOUT_VERSION, &
                          PACK_HEADER_WORDS, BODY_WORDS
  use body_fixtures, only: filled_bodies, same_row
  use assertions
  implicit none

  call round_trip()
  call empty_selection()
  call bad_buffers()
  call test_finish()

contains

  subroutine round_trip()
    type(bodies_t) :: src, dst, dst0
    type(error_t) :: err
    real(dp), allocatable :: buffer(:)
    integer(i8) :: extra(2, 7)
    integer(i8), allocatable :: got(:, :)
    integer, parameter :: ROWS(4) = [6, 1, 3, 7]     ! ghosts 6 and 7 among owned 1 and 3
    integer :: k, first
    logical :: ok
    call filled_bodies(5, 2, 11, 2_i8**40, src)
    do k = 1, 7
      extra(:, k) = [int(k, i8)*3_i8, -1_i8]
    end do
    extra(1, 3) = huge(1_i8)
    call pack_bodies(src, ROWS, buffer, extra)
    call check(size(buffer) == packed_words(4, 2) .and. size(buffer) == PACK_HEADER_WORDS + 4*(BODY_WORDS + 2), &
               'buffer length: header + 4 records of 31 + 2 words')
    call check(packed_count(buffer) == 4 .and. transfer(buffer(1), 1_i8) == PACK_LAYOUT_VERSION, &
               'header: layout version and count')
    ! into a rank holding 2 owned and 3 ghosts: as owned rows
    call filled_bodies(2, 3, 12, 9000_i8, dst)
    dst0 = dst
    call unpack_bodies(buffer, dst, .false., err, first, got)
    call check(err%ok() .and. dst%n_owned == 6 .and. dst%n_ghost == 3 .and. first == 3, &
               'unpack as owned: counts 6 + 3, first row 3')
    ok = .true.
    do k = 1, 4
      if (.not. same_row(dst, first + k - 1, src, ROWS(k))) ok = .false.
      if (any(got(:, k) /= extra(:, ROWS(k)))) ok = .false.
    end do
    call check(ok, 'unpack as owned: rows and extras bitwise')
    call check(same_row(dst, 1, dst0, 1) .and. same_row(dst, 2, dst0, 2) .and. same_row(dst, 7, dst0, 3) .and. &
               same_row(dst, 9, dst0, 5), 'unpack as owned: the rank''s ghosts move up in order')
    ! the same buffer as ghosts
    call unpack_bodies(buffer, dst, .true., err, first)
    call check(err%ok() .and. dst%n_owned == 6 .and. dst%n_ghost == 7 .and. first == 10, &
               'unpack as ghosts: counts 6 + 7, at the end')
    ok = .true.
    do k = 1, 4
      if (.not. same_row(dst, first + k - 1, src, ROWS(k))) ok = .false.
    end do
    call check(ok, 'unpack as ghosts: rows bitwise')
    call check(transfer(dst%v(2, 4), 1_i8) == transfer(-0.0_dp, 1_i8) .and. dst%a(1, 4) == huge(1.0_dp) .and. &
               dst%w(3, 4) == tiny(1.0_dp)*0.5_dp**20, 'the -0.0, huge and subnormal of row 1 survive')
    ! packing without extras: 31 words a body, and extras asked for come back empty
    call pack_bodies(src, [2], buffer)
    call check(size(buffer) == PACK_HEADER_WORDS + BODY_WORDS, 'no extras: 31 words a body')
    call unpack_bodies(buffer, dst, .true., err, first, got)
    call check(err%ok() .and. size(got, 1) == 0 .and. size(got, 2) == 1 .and. same_row(dst, first, src, 2), &
               'no extras: row bitwise, extras 0 x 1')
  end subroutine round_trip

  subroutine empty_selection()
    type(bodies_t) :: src, dst
    type(error_t) :: err
    real(dp), allocatable :: buffer(:)
    call filled_bodies(3, 0, 13, 0_i8, src)
    call filled_bodies(1, 1, 14, 0_i8, dst)
    call pack_bodies(src, [integer ::], buffer)
    call check(size(buffer) == PACK_HEADER_WORDS .and. packed_count(buffer) == 0, 'empty selection: header only')
    call unpack_bodies(buffer, dst, .false., err)
    call check(err%ok() .and. dst%n_owned == 1 .and. dst%n_ghost == 1, 'empty buffer: nothing appended')
  end subroutine empty_selection

  subroutine bad_buffers()
    type(bodies_t) :: src, dst
    type(error_t) :: err
    real(dp), allocatable :: buffer(:)
    call filled_bodies(3, 0, 15, 0_i8, src)
    call filled_bodies(2, 0, 16, 0_i8, dst)
    call pack_bodies(src, [1, 2], buffer)
    call unpack_bodies(buffer(1:size(buffer) - 1), dst, .false., err)
    call check_error(err%code, err%message, [character(len=24) :: 'body buffer', '2 bodies', '31 words', &
                     '65 words'], 'a truncated buffer')
    call err%clear()
    buffer(1) = transfer(int(PACK_LAYOUT_VERSION + 1, i8), 1.0_dp)
    call unpack_bodies(buffer, dst, .false., err)
    call check_error(err%code, err%message, [character(len=24) :: 'layout version 2', 'reads 1'], 'a foreign layout')
    call err%clear()
    call unpack_bodies(buffer(1:2), dst, .false., err)
    call check_error(err%code, err%message, [character(len=24) :: 'shorter than its header'], 'no header')
    call check(dst%n_owned == 2 .and. dst%n_ghost == 0, 'bad buffers leave the bodies alone')
    call check(packed_count(buffer) == -1, 'packed_count of a foreign buffer: -1')
  end subroutine bad_buffers

end program test_body_packing
