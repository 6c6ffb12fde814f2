!> bodies_t row operations (migration and ghosts): copy_row copies every field bitwise;
!> append_rows/append_row put owned rows before the ghosts (which move up in order) and
!> ghost rows at the end, growing the capacity geometrically (16, then doubling) and
!> keeping every row; remove_rows (mask or list, repeats allowed) keeps the order of the
!> rest with owned first and the counts right, and its new_index maps old rows to new;
!> bad masks and rows are errors, not crashes; sort_owned_by_gid orders the owned rows by
!> global id and leaves the ghosts. Rows are compared as bit patterns (exact: rows are only
!> moved, never computed).
program test_body_rows
  use kinds, only: dp, i8
  use body_state, only: bodies_t, copy_row
  use error_status, only: error_t
  use body_fixtures, only: filled_bodies, same_row
  use assertions
  implicit none

  call copy_rows()
  call append_owned_and_ghosts()
  call capacity_growth()
  call remove_by_mask_and_list()
  call remove_errors()
  call sort_by_gid()
  call test_finish()

contains

  subroutine copy_rows()
    type(bodies_t) :: a, b
    integer :: i
    logical :: ok
    call filled_bodies(4, 2, 1, 1000_i8, a)
    call b%allocate(6)
    ok = .true.
    do i = 1, 6
      call copy_row(a, i, b, 7 - i)
    end do
    do i = 1, 6
      if (.not. same_row(a, i, b, 7 - i)) ok = .false.
    end do
    call check(ok, 'copy_row: every field bitwise (reversed rows)')
    call check(b%n_owned == 0 .and. b%n_ghost == 0, 'copy_row leaves the counts alone')
    call check(transfer(b%v(2, 6), 1_i8) == transfer(-0.0_dp, 1_i8), 'copy_row keeps -0.0')
  end subroutine copy_rows

  subroutine append_owned_and_ghosts()
    type(bodies_t) :: a, src, orig
    integer :: i
    logical :: ok
    call filled_bodies(3, 2, 2, 0_i8, a)
    orig = a
    call filled_bodies(5, 0, 3, 5000_i8, src)
    call a%append_rows(src, [4, 2], .false.)
    call check(a%n_owned == 5 .and. a%n_ghost == 2, 'append owned rows: counts 5 + 2')
    ok = same_row(a, 1, orig, 1) .and. same_row(a, 2, orig, 2) .and. same_row(a, 3, orig, 3) .and. &
         same_row(a, 4, src, 4) .and. same_row(a, 5, src, 2) .and. same_row(a, 6, orig, 4) .and. &
         same_row(a, 7, orig, 5)
    call check(ok, 'append owned rows: after the owned, before the ghosts, which keep their order')
    call a%append_rows(src, [1, 5], .true.)
    call check(a%n_owned == 5 .and. a%n_ghost == 4, 'append ghost rows: counts 5 + 4')
    call check(same_row(a, 8, src, 1) .and. same_row(a, 9, src, 5) .and. same_row(a, 7, orig, 5), &
               'append ghost rows: at the end, in order')
    call a%append_row(src, 3, .false.)
    call check(a%n_owned == 6 .and. a%n_ghost == 4 .and. same_row(a, 6, src, 3) .and. &
               same_row(a, 7, orig, 4) .and. same_row(a, 10, src, 5), 'append_row: one owned row')
    call a%append_rows(src, [integer ::], .false.)
    call check(a%n_owned == 6 .and. a%n_ghost == 4 .and. same_row(a, 7, orig, 4), 'append no rows: nothing moves')
    ok = .true.
    do i = 1, a%n_total()
      if (count(a%gid(1:a%n_total()) == a%gid(i)) /= 1) ok = .false.
    end do
    call check(ok, 'appended rows: every gid once')
  end subroutine append_owned_and_ghosts

  subroutine capacity_growth()
    type(bodies_t) :: a, src
    integer :: i, grows, last_capacity
    logical :: ok
    call filled_bodies(40, 0, 4, 0_i8, src)
    call a%allocate(0)
    call check(a%capacity() == 0, 'empty bodies: capacity 0')
    grows = 0
    last_capacity = 0
    do i = 1, 40
      call a%append_row(src, i, mod(i, 5) == 0)
      if (a%capacity() /= last_capacity) then
        grows = grows + 1
        last_capacity = a%capacity()
      end if
    end do
    call check(a%capacity() == 64 .and. grows == 3, 'appending 40 rows one by one grows 16 -> 32 -> 64')
    call check(a%n_owned == 32 .and. a%n_ghost == 8, 'appending 40 rows: 32 owned, 8 ghosts')
    ok = .true.
    do i = 1, 40
      if (mod(i, 5) == 0) then
        if (.not. same_row(a, 32 + i/5, src, i)) ok = .false.
      else
        if (.not. same_row(a, i - i/5, src, i)) ok = .false.
      end if
    end do
    call check(ok, 'appending 40 rows: every row kept through the growths, owned then ghosts in order')
    call a%reserve(10)
    call check(a%capacity() == 64, 'reserve never shrinks')
  end subroutine capacity_growth

  subroutine remove_by_mask_and_list()
    type(bodies_t) :: a, orig
    type(error_t) :: err
    logical :: remove(8)
    integer :: new_index(8), i
    logical :: ok
    call filled_bodies(5, 3, 5, 0_i8, a)
    orig = a
    remove = .false.
    remove([2, 5, 7]) = .true.      ! two owned, one ghost
    call a%remove_rows(remove, err, new_index)
    call check(err%ok() .and. a%n_owned == 3 .and. a%n_ghost == 2, 'remove by mask: counts 3 + 2')
    call check(all(new_index == [1, 0, 2, 3, 0, 4, 0, 5]), 'remove by mask: new_index')
    ok = .true.
    do i = 1, 8
      if (new_index(i) > 0) then
        if (.not. same_row(a, new_index(i), orig, i)) ok = .false.
      end if
    end do
    call check(ok, 'remove by mask: the others keep their order, owned first')
    ! by list, with a repeat: the last owned and the first ghost
    call a%remove_rows([3, 4, 3], err, new_index(1:5))
    call check(err%ok() .and. a%n_owned == 2 .and. a%n_ghost == 1, 'remove by list: counts 2 + 1')
    call check(same_row(a, 1, orig, 1) .and. same_row(a, 2, orig, 3) .and. same_row(a, 3, orig, 8), &
               'remove by list: rows left')
    call a%remove_rows([1, 2, 3], err)
    call check(err%ok() .and. a%n_total() == 0, 'remove every row')
  end subroutine remove_by_mask_and_list

  subroutine remove_errors()
    type(bodies_t) :: a
    type(error_t) :: err
    call filled_bodies(2, 1, 6, 0_i8, a)
    call a%remove_rows([.true., .false.], err)
    call check_error(err%code, err%message, [character(len=16) :: 'mask of 2', '3 bodies'], 'remove: mask size')
    call err%clear()
    call a%remove_rows([1, 4], err)
    call check_error(err%code, err%message, [character(len=16) :: 'row 4', '1..3'], 'remove: row out of range')
    call check(a%n_owned == 2 .and. a%n_ghost == 1, 'a failed remove leaves the rows')
  end subroutine remove_errors

  subroutine sort_by_gid()
    type(bodies_t) :: a, orig
    integer :: new_index(7), i
    logical :: ok
    call filled_bodies(5, 2, 7, 0_i8, a)
    a%gid(1:5) = [50_i8, 10_i8, 40_i8, 20_i8, 30_i8]
    a%gid(6:7) = [5_i8, 1_i8]
    orig = a
    call a%sort_owned_by_gid(new_index)
    call check(all(a%gid == [10_i8, 20_i8, 30_i8, 40_i8, 50_i8, 5_i8, 1_i8]), 'sort_owned_by_gid: owned sorted, ghosts left')
    ok = .true.
    do i = 1, 7
      if (.not. same_row(a, new_index(i), orig, i)) ok = .false.
    end do
    call check(ok, 'sort_owned_by_gid: whole rows move, new_index says where')
  end subroutine sort_by_gid

end program test_body_rows
