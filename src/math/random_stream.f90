!> A small deterministic random stream (SplitMix64 seeding xoshiro256**): the same seed gives
!> the same numbers on every compiler and machine, which `random_number` does not promise.
!> Used for the lattice jitter of a deck, so decks are reproducible from their `seed`.
module random_stream
  use kinds, only: dp, i8
  implicit none
  private
  public :: random_stream_t

  type :: random_stream_t
    integer(i8) :: s(4) = 0
  contains
    procedure :: init => stream_init
    procedure :: next_u64 => stream_next
    procedure :: uniform => stream_uniform
    procedure :: symmetric => stream_symmetric
    procedure :: unit_vector => stream_unit_vector
  end type random_stream_t

contains

  !> Seeds the state from one integer through SplitMix64, as the xoshiro authors advise.
  pure subroutine stream_init(self, seed)
    class(random_stream_t), intent(inout) :: self
    integer, intent(in) :: seed
    integer(i8) :: z, x
    integer :: k
    x = int(seed, i8)
    do k = 1, 4
      x = x + int(z'9E3779B97F4A7C15', i8)
      z = x
      z = ieor(z, shiftr(z, 30))*int(z'BF58476D1CE4E5B9', i8)
      z = ieor(z, shiftr(z, 27))*int(z'94D049BB133111EB', i8)
      self%s(k) = ieor(z, shiftr(z, 31))
    end do
  end subroutine stream_init

  !> xoshiro256** (Blackman & Vigna): 64 random bits. The algorithm needs integer overflow
  !> to wrap (two's complement): this file is compiled with -fwrapv (src/CMakeLists.txt).
  integer(i8) function stream_next(self)
    class(random_stream_t), intent(inout) :: self
    integer(i8) :: t
    stream_next = ishftc(self%s(2)*5_i8, 7)*9_i8
    t = shiftl(self%s(2), 17)
    self%s(3) = ieor(self%s(3), self%s(1))
    self%s(4) = ieor(self%s(4), self%s(2))
    self%s(2) = ieor(self%s(2), self%s(3))
    self%s(1) = ieor(self%s(1), self%s(4))
    self%s(3) = ieor(self%s(3), t)
    self%s(4) = ishftc(self%s(4), 45)
  end function stream_next

  !> Uniform in [0, 1) with 53 random bits.
  real(dp) function stream_uniform(self)
    class(random_stream_t), intent(inout) :: self
    stream_uniform = real(shiftr(self%next_u64(), 11), dp)*2.0_dp**(-53)
  end function stream_uniform

  !> Uniform in [-half_width, half_width).
  real(dp) function stream_symmetric(self, half_width)
    class(random_stream_t), intent(inout) :: self
    real(dp), intent(in) :: half_width
    stream_symmetric = half_width*(2.0_dp*self%uniform() - 1.0_dp)
  end function stream_symmetric

  !> Direction uniform on the unit sphere (Marsaglia's rejection-free z/phi method).
  function stream_unit_vector(self) result(u)
    class(random_stream_t), intent(inout) :: self
    real(dp) :: u(3), z, phi, r
    z = 2.0_dp*self%uniform() - 1.0_dp
    phi = 6.283185307179586476925286766559_dp*self%uniform()
    r = sqrt(max(0.0_dp, 1.0_dp - z*z))
    u = [r*cos(phi), r*sin(phi), z]
  end function stream_unit_vector

end module random_stream
