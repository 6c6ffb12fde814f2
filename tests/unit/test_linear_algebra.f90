!> symmetric_eigen: diagonal, rotated, degenerate and invalid inputs; ascending values,
!> orthonormal right-handed vectors, deterministic bases of degenerate eigenspaces.
!> Tolerances: the matrices have entries O(1) and eigenvalue gaps >= 1 (or exact
!> degeneracy), so LAPACK's backward-stable results are accurate to a few 1e-15; 1e-13 is a
!> margin of ~30 that still catches any mispairing or sign/ordering error (O(1) errors).
program test_linear_algebra
  use, intrinsic :: ieee_arithmetic, only: ieee_value, ieee_positive_inf
  use kinds, only: dp
  use linear_algebra, only: symmetric_eigen
  use error_status, only: error_t, ERR_INTERNAL, ERR_NUMERIC
  use quaternion, only: quat_exp, quat_to_matrix
  use string_utils, only: str
  use assertions
  implicit none

  real(dp), parameter :: tol = 1.0e-13_dp

  call test_diagonal()
  call test_cube_like()
  call test_rotated()
  call test_degenerate_pair()
  call test_multiple_of_identity()
  call test_axisymmetric_near_diagonal()
  call test_general_n()
  call test_errors()
  call test_finish()

contains

  pure real(dp) function det3(m)
    real(dp), intent(in) :: m(3, 3)
    det3 = m(1, 1)*(m(2, 2)*m(3, 3) - m(3, 2)*m(2, 3)) - m(1, 2)*(m(2, 1)*m(3, 3) - m(3, 1)*m(2, 3)) &
           + m(1, 3)*(m(2, 1)*m(3, 2) - m(3, 1)*m(2, 2))
  end function det3

  pure function diag3(d) result(m)
    real(dp), intent(in) :: d(3)
    real(dp) :: m(3, 3)
    m = 0.0_dp
    m(1, 1) = d(1); m(2, 2) = d(2); m(3, 3) = d(3)
  end function diag3

  !> Checks shared by every case: A V = V diag(values), V^T V = 1, values ascending, det +1.
  subroutine check_decomposition(a, values, vectors, what)
    real(dp), intent(in) :: a(:, :), values(:), vectors(:, :)
    character(len=*), intent(in) :: what
    real(dp) :: scale
    integer :: k, n
    n = size(values)
    scale = maxval(abs(a))
    do k = 1, n
      call check_close_array(matmul(a, vectors(:, k)), values(k)*vectors(:, k), 0.0_dp, &
                             what//': A v = lambda v for column '//str(k), atol=tol*scale)
    end do
    call check(maxval(abs(matmul(transpose(vectors), vectors) - identity(n))) < tol, what//': orthonormal')
    call check(all(values(2:n) >= values(1:n - 1)), what//': values ascending')
    if (n == 3) call check_close(det3(vectors), 1.0_dp, tol, what//': right-handed (det +1)')
  end subroutine check_decomposition

  pure function identity(n) result(e)
    integer, intent(in) :: n
    real(dp) :: e(n, n)
    integer :: i
    e = 0.0_dp
    do i = 1, n
      e(i, i) = 1.0_dp
    end do
  end function identity

  subroutine eigen(a, values, vectors, what)
    real(dp), intent(in) :: a(:, :)
    real(dp), intent(out) :: values(:), vectors(:, :)
    character(len=*), intent(in) :: what
    type(error_t) :: err
    call symmetric_eigen(a, values, vectors, err)
    call check(err%ok(), what//': no error')
  end subroutine eigen

  subroutine test_diagonal()
    real(dp) :: a(3, 3), values(3), vectors(3, 3), expected(3, 3)
    a = diag3([3.0_dp, 1.0_dp, 2.0_dp])
    ! Tiny off-diagonal noise (1e-15 relative, below the 1e-12 diagonal test) changes nothing.
    a(1, 2) = 3.0e-15_dp; a(2, 1) = 3.0e-15_dp
    call eigen(a, values, vectors, 'diagonal')
    call check_close_array(values, [1.0_dp, 2.0_dp, 3.0_dp], 0.0_dp, 'diagonal: sorted diagonal, exactly')
    ! Axes e2, e3, e1: a cyclic permutation, already right-handed; exact 0/1 entries.
    expected = 0.0_dp
    expected(2, 1) = 1.0_dp; expected(3, 2) = 1.0_dp; expected(1, 3) = 1.0_dp
    call check(all(vectors == expected), 'diagonal: coordinate axes exactly')
    call check_decomposition(a, values, vectors, 'diagonal')
    ! Order (z, y, x) is odd: the third column is flipped to keep det +1.
    call eigen(diag3([3.0_dp, 2.0_dp, 1.0_dp]), values, vectors, 'reversed diagonal')
    expected = 0.0_dp
    expected(3, 1) = 1.0_dp; expected(2, 2) = 1.0_dp; expected(1, 3) = -1.0_dp
    call check(all(vectors == expected), 'reversed diagonal: e3, e2, -e1')
    call check_decomposition(diag3([3.0_dp, 2.0_dp, 1.0_dp]), values, vectors, 'reversed diagonal')
  end subroutine test_diagonal

  !> A cube's tensor from a mesh: diagonal with round-off differences between the moments;
  !> the frame must stay the identity (not a permutation chosen by the round-off).
  subroutine test_cube_like()
    real(dp) :: values(3), vectors(3, 3)
    call eigen(diag3([1.0_dp/6.0_dp + 2.0e-17_dp, 1.0_dp/6.0_dp, 1.0_dp/6.0_dp - 2.0e-17_dp]), values, vectors, &
               'cube-like')
    call check(all(vectors == identity(3)), 'cube-like: identity frame')
    call check(all(values(2:3) >= values(1:2)), 'cube-like: values ascending')
  end subroutine test_cube_like

  subroutine test_rotated()
    real(dp) :: r(3, 3), a(3, 3), values(3), vectors(3, 3)
    integer :: k
    r = quat_to_matrix(quat_exp([0.4_dp, -1.1_dp, 2.3_dp]))
    a = matmul(r, matmul(diag3([1.0_dp, 2.0_dp, 4.0_dp]), transpose(r)))
    call eigen(a, values, vectors, 'rotated')
    call check_close_array(values, [1.0_dp, 2.0_dp, 4.0_dp], tol, 'rotated: eigenvalues')
    ! Each eigenvector is a column of r up to sign (gaps >= 1: accurate to round-off).
    do k = 1, 3
      call check_close(abs(dot_product(vectors(:, k), r(:, k))), 1.0_dp, tol, 'rotated: vector '//str(k))
      ! Sign convention: largest component positive, except that column 3 may be flipped
      ! for det +1.
      if (k < 3) call check(vectors(maxloc(abs(vectors(:, k)), dim=1), k) > 0.0_dp, &
                            'rotated: vector '//str(k)//' largest component positive')
    end do
    call check_decomposition(a, values, vectors, 'rotated')
  end subroutine test_rotated

  !> An axisymmetric tensor (moments 2, 2, 5) in two presentations that differ by a turn
  !> about the symmetry axis: same matrix up to round-off, so the (canonical) basis of the
  !> degenerate plane must agree to round-off, whatever basis LAPACK picked.
  subroutine test_degenerate_pair()
    real(dp) :: r(3, 3), spin(3, 3), a1(3, 3), a2(3, 3), v1(3), v2(3), e1(3, 3), e2(3, 3), axis(3)
    r = quat_to_matrix(quat_exp([0.9_dp, 0.3_dp, -0.5_dp]))
    axis = r(:, 3)
    spin = quat_to_matrix(quat_exp(1.234_dp*axis))
    a1 = matmul(r, matmul(diag3([2.0_dp, 2.0_dp, 5.0_dp]), transpose(r)))
    a2 = matmul(matmul(spin, r), matmul(diag3([2.0_dp, 2.0_dp, 5.0_dp]), transpose(matmul(spin, r))))
    call check(maxval(abs(a1 - a2)) < 1.0e-14_dp, 'degenerate pair: same tensor up to round-off')
    call eigen(a1, v1, e1, 'degenerate pair 1')
    call eigen(a2, v2, e2, 'degenerate pair 2')
    call check_close_array(v1, [2.0_dp, 2.0_dp, 5.0_dp], tol, 'degenerate pair: eigenvalues')
    call check_decomposition(a1, v1, e1, 'degenerate pair 1')
    call check_decomposition(a2, v2, e2, 'degenerate pair 2')
    call check_close(abs(dot_product(e1(:, 3), axis)), 1.0_dp, tol, 'degenerate pair: distinct axis')
    ! Round-off of 1e-16 in the tensor moves the canonical basis by ~1e-16/(gap 3): 1e-13.
    call check_close_array(reshape(e1, [9]), reshape(e2, [9]), 0.0_dp, 'degenerate pair: same canonical basis', &
                           atol=tol)
  end subroutine test_degenerate_pair

  subroutine test_multiple_of_identity()
    real(dp) :: values(3), vectors(3, 3)
    call eigen(diag3([7.0_dp, 7.0_dp, 7.0_dp]), values, vectors, '7 I')
    call check(all(vectors == identity(3)) .and. all(values == 7.0_dp), '7 I: identity frame, values 7')
  end subroutine test_multiple_of_identity

  !> Axisymmetric about z with off-diagonal terms just above the diagonal test (~4e-12
  !> relative, so LAPACK runs): the (tilted) x-y plane is one eigenspace, and its canonical
  !> basis must start with ~e1 (a near-tie |P e1| ~ |P e2| to ~1e-22, broken by index, not
  !> by round-off: with these numbers a plain largest-norm pivot picks e2 first). The frame
  !> is the identity up to the ~1e-11 perturbation (1e-10 allows a factor 10).
  subroutine test_axisymmetric_near_diagonal()
    real(dp) :: a(3, 3), values(3), vectors(3, 3)
    a = diag3([2.0_dp, 2.0_dp, 5.0_dp])
    a(1, 3) = 1.3e-11_dp; a(3, 1) = a(1, 3)
    a(2, 3) = -2.1e-11_dp; a(3, 2) = a(2, 3)
    a(1, 2) = a(1, 3)*a(2, 3); a(2, 1) = a(1, 2)
    call eigen(a, values, vectors, 'axisymmetric near-diagonal')
    call check_close_array(reshape(vectors, [9]), reshape(identity(3), [9]), 0.0_dp, &
                           'axisymmetric near-diagonal: identity-aligned frame', atol=1.0e-10_dp)
    call check_decomposition(a, values, vectors, 'axisymmetric near-diagonal')
  end subroutine test_axisymmetric_near_diagonal

  !> n = 4 through LAPACK: a tridiagonal (1D Laplacian) with known eigenvalues
  !> 2 - 2 cos(k pi/5), k = 1..4.
  subroutine test_general_n()
    real(dp) :: a(4, 4), values(4), vectors(4, 4), expected(4)
    integer :: k
    a = 0.0_dp
    do k = 1, 4
      a(k, k) = 2.0_dp
      if (k < 4) then
        a(k, k + 1) = -1.0_dp
        a(k + 1, k) = -1.0_dp
      end if
      expected(k) = 2.0_dp - 2.0_dp*cos(k*acos(-1.0_dp)/5.0_dp)
    end do
    call eigen(a, values, vectors, 'laplacian 4')
    call check_close_array(values, expected, tol, 'laplacian 4: eigenvalues 2 - 2 cos(k pi/5)')
    call check_decomposition(a, values, vectors, 'laplacian 4')
  end subroutine test_general_n

  subroutine test_errors()
    real(dp) :: values(2), vectors(3, 3), a(3, 3)
    type(error_t) :: err
    call symmetric_eigen(identity(3), values, vectors, err)
    call check_error(err%code, err%message, [character(len=20) :: 'inconsistent sizes'], 'size mismatch refused')
    call check(err%code == ERR_INTERNAL, 'size mismatch: ERR_INTERNAL')
    a = identity(3)
    ! ieee_value builds the infinity without arithmetic that would trap in Debug builds.
    a(2, 3) = ieee_value(1.0_dp, ieee_positive_inf)
    a(3, 2) = a(2, 3)
    call symmetric_eigen(a, values(1:2), vectors(1:2, 1:2), err)
    call check(err%code == ERR_INTERNAL, 'non-square slices: size error first')
    block
      real(dp) :: v3(3)
      call symmetric_eigen(a, v3, vectors, err)
      call check_error(err%code, err%message, [character(len=20) :: 'NaN or infinite'], 'infinite entry refused')
      call check(err%code == ERR_NUMERIC, 'infinite entry: ERR_NUMERIC')
    end block
  end subroutine test_errors

end program test_linear_algebra
