!> Bodies with a distinct value in every field of every row, for the row operations and
!> the body packing tests, and a row's bit pattern to compare rows exactly (-0.0 and 0.0,
!> or two NaNs, differ there as they would in a checkpoint).
module body_fixtures
  use, intrinsic :: iso_fortran_env, only: dp => real64, i8 => int64
  use body_state, only: bodies_t
  use random_stream, only: random_stream_t
  implicit none
  private
  public :: filled_bodies, row_bits, same_row, ROW_BITS_WORDS

  integer, parameter :: ROW_BITS_WORDS = 4 + 27

contains

  !> n_owned owned rows then n_ghost ghosts, gids gid0 + 7*row (distinct, large), every
  !> real from a seeded stream, some of them edge cases: -0.0, a subnormal, huge.
  subroutine filled_bodies(n_owned, n_ghost, seed, gid0, b)
    integer, intent(in) :: n_owned, n_ghost
    integer, intent(in) :: seed
    integer(i8), intent(in) :: gid0
    type(bodies_t), intent(inout) :: b
    type(random_stream_t) :: rng
    integer :: i, k
    call rng%init(seed)
    call b%allocate(n_owned + n_ghost)
    b%n_owned = n_owned
    b%n_ghost = n_ghost
    do i = 1, n_owned + n_ghost
      b%gid(i) = gid0 + 7_i8*i
      b%shape_id(i) = 1 + mod(i, 3)
      b%group_id(i) = 100 + i
      b%fixed(i) = mod(i, 4) == 0
      b%asleep(i) = mod(i, 3) == 0
      b%mass(i) = 1.0_dp + rng%uniform()
      b%inv_mass(i) = 1.0_dp/b%mass(i)
      do k = 1, 3
        b%inertia(k, i) = rng%uniform()
        b%inv_inertia(k, i) = rng%symmetric(1.0_dp)
        b%x(k, i) = rng%symmetric(10.0_dp)
        b%v(k, i) = rng%symmetric(3.0_dp)
        b%w(k, i) = rng%symmetric(5.0_dp)
        b%a(k, i) = rng%symmetric(9.81_dp)
        b%alpha(k, i) = rng%symmetric(1.0_dp)
      end do
      b%q(:, i) = [rng%symmetric(1.0_dp), rng%symmetric(1.0_dp), rng%symmetric(1.0_dp), rng%symmetric(1.0_dp)]
      b%q(:, i) = b%q(:, i)/norm2(b%q(:, i))
    end do
    if (n_owned + n_ghost >= 1) then
      b%v(2, 1) = -0.0_dp
      b%w(3, 1) = tiny(1.0_dp)*0.5_dp**20     ! subnormal
      b%a(1, 1) = huge(1.0_dp)
    end if
  end subroutine filled_bodies

  !> Every field of row i as 64-bit patterns (logicals and integers as 0/1 and values).
  function row_bits(b, i) result(bits)
    type(bodies_t), intent(in) :: b
    integer, intent(in) :: i
    integer(i8) :: bits(ROW_BITS_WORDS)
    real(dp) :: reals(27)
    bits(1) = b%gid(i)
    bits(2) = b%shape_id(i)
    bits(3) = b%group_id(i)
    bits(4) = merge(1_i8, 0_i8, b%fixed(i)) + merge(2_i8, 0_i8, b%asleep(i))
    reals = [b%mass(i), b%inv_mass(i), b%inertia(:, i), b%inv_inertia(:, i), b%x(:, i), b%q(:, i), &
             b%v(:, i), b%w(:, i), b%a(:, i), b%alpha(:, i)]
    bits(5:) = transfer(reals, bits(5:))
  end function row_bits

  !> Rows i of a and j of b hold the same bits in every field.
  logical function same_row(a, i, b, j)
    type(bodies_t), intent(in) :: a, b
    integer, intent(in) :: i, j
    same_row = all(row_bits(a, i) == row_bits(b, j))
  end function same_row

end module body_fixtures
