!> Digests that tell whether data changed: a checkpoint's body state (damage on disk, an
!> edited file) and a shape's geometry (a mesh file swapped, a scale changed on restart).
!>
!> A digest is two polynomial hashes of the data's 32-bit words, modulo two primes near
!> 2^31 (h <- h*B + w mod p): every product stays below 2^57, so the arithmetic is exact
!> in 64-bit integers with no wrapping, and the pair distinguishes ~2^62 values. Doubles
!> enter by their bit patterns, so any changed bit (and -0.0 against 0.0) changes it.
!> A collection of records (bodies) is digested order-independently as the sum of its
!> records' digests modulo the primes: the same whatever the number of ranks and the order
!> in which they hold the records.
module digest
  use kinds, only: dp, i8
  implicit none
  private
  public :: digest_t, digest_sum, digest_parts, digest_from_parts

  integer(i8), parameter :: prime(2) = [2147483647_i8, 2147483629_i8]   ! 2^31 - 1, 2^31 - 19
  integer(i8), parameter :: base(2) = [16777619_i8, 40503_i8]
  integer(i8), parameter :: low_word = 4294967295_i8                   ! 2^32 - 1

  type :: digest_t
    integer(i8) :: h(2) = [7_i8, 11_i8]
  contains
    procedure :: add_reals => digest_add_reals
    procedure :: add_real => digest_add_real
    procedure :: add_ints => digest_add_ints
    procedure :: add_int => digest_add_int
    procedure :: add_int8 => digest_add_int8
    procedure :: value => digest_value
  end type digest_t

contains

  pure subroutine add_word(self, word)
    class(digest_t), intent(inout) :: self
    integer(i8), intent(in) :: word      !< 0 <= word < 2^32
    self%h = mod(self%h*base + mod(word, prime), prime)
  end subroutine add_word

  pure subroutine digest_add_int8(self, value)
    class(digest_t), intent(inout) :: self
    integer(i8), intent(in) :: value
    call add_word(self, iand(value, low_word))
    call add_word(self, iand(shiftr(value, 32), low_word))
  end subroutine digest_add_int8

  pure subroutine digest_add_real(self, value)
    class(digest_t), intent(inout) :: self
    real(dp), intent(in) :: value
    call digest_add_int8(self, transfer(value, 0_i8))
  end subroutine digest_add_real

  pure subroutine digest_add_reals(self, values)
    class(digest_t), intent(inout) :: self
    real(dp), intent(in) :: values(:)
    integer :: i
    do i = 1, size(values)
      call digest_add_int8(self, transfer(values(i), 0_i8))
    end do
  end subroutine digest_add_reals

  pure subroutine digest_add_int(self, value)
    class(digest_t), intent(inout) :: self
    integer, intent(in) :: value
    call add_word(self, iand(int(value, i8), low_word))
  end subroutine digest_add_int

  pure subroutine digest_add_ints(self, values)
    class(digest_t), intent(inout) :: self
    integer, intent(in) :: values(:)
    integer :: i
    do i = 1, size(values)
      call add_word(self, iand(int(values(i), i8), low_word))
    end do
  end subroutine digest_add_ints

  !> The digest as one non-negative 64-bit number (h1 * 2^31 + h2 < 2^62).
  pure integer(i8) function digest_value(self)
    class(digest_t), intent(in) :: self
    digest_value = self%h(1)*2147483648_i8 + self%h(2)
  end function digest_value

  !> Order-independent sum of record digests given as digest_value numbers (any order,
  !> any grouping: partial sums of ranks may be summed again). Each part is reduced as it
  !> goes, so any number of records fits.
  pure integer(i8) function digest_sum(values) result(total)
    integer(i8), intent(in) :: values(:)
    integer(i8) :: h(2)
    integer :: i
    h = 0
    do i = 1, size(values)
      h(1) = mod(h(1) + shiftr(values(i), 31), prime(1))
      h(2) = mod(h(2) + iand(values(i), 2147483647_i8), prime(2))
    end do
    total = h(1)*2147483648_i8 + h(2)
  end function digest_sum

  !> The two hash parts of a digest value (each below 2^31): ranks sum these (exact in 64
  !> bits for up to 2^32 ranks) and digest_from_parts reduces the sums.
  pure function digest_parts(value) result(h)
    integer(i8), intent(in) :: value
    integer(i8) :: h(2)
    h = [shiftr(value, 31), iand(value, 2147483647_i8)]
  end function digest_parts

  pure integer(i8) function digest_from_parts(h) result(value)
    integer(i8), intent(in) :: h(2)
    value = mod(h(1), prime(1))*2147483648_i8 + mod(h(2), prime(2))
  end function digest_from_parts

end module digest
