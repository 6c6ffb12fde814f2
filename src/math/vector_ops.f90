!> Small 3-vector helpers shared by geometry and dynamics.
module vector_ops
  use kinds, only: dp
  implicit none
  private
  public :: cross, outer, skew, identity3

contains

  pure function cross(a, b) result(c)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: c(3)
    c = [a(2)*b(3) - a(3)*b(2), a(3)*b(1) - a(1)*b(3), a(1)*b(2) - a(2)*b(1)]
  end function cross

  pure function outer(a, b) result(m)
    real(dp), intent(in) :: a(3), b(3)
    real(dp) :: m(3, 3)
    integer :: j
    do j = 1, 3
      m(:, j) = a*b(j)
    end do
  end function outer

  !> Matrix of the cross product: skew(a) b = a x b.
  pure function skew(a) result(m)
    real(dp), intent(in) :: a(3)
    real(dp) :: m(3, 3)
    m = reshape([0.0_dp, a(3), -a(2), -a(3), 0.0_dp, a(1), a(2), -a(1), 0.0_dp], [3, 3])
  end function skew

  pure function identity3() result(m)
    real(dp) :: m(3, 3)
    m = 0.0_dp
    m(1, 1) = 1.0_dp; m(2, 2) = 1.0_dp; m(3, 3) = 1.0_dp
  end function identity3

end module vector_ops
