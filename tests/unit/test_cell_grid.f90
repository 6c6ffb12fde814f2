!> cell_grid (the local event loop's broad phase): regions found by overlap, large regions
!> kept out of the boxes, and box coordinates past 2^31 (a 1e4 m body in 2e-6 m boxes, the
!> size ratio 1e10 of check_stress.py `scales`): there the default-kind floor() overflowed,
!> the 1e4 m body was listed nowhere and a 1e-6 m sphere fell through it.
program test_cell_grid
  use kinds, only: dp, i8
  use error_status, only: error_t
  use cell_grid, only: cell_grid_t
  use assertions, only: check, test_finish
  implicit none
  type(cell_grid_t) :: grid
  type(error_t) :: err
  integer, allocatable :: found(:)
  integer :: n_found
  real(dp), parameter :: h = 2.0e-6_dp        ! box edge [m]: a 1e-6 m sphere's extent
  real(dp), parameter :: big = 1.0e4_dp       ! [m] a planet's radius: 5e9 boxes > 2^31
  real(dp), parameter :: far = 2.0_dp**40*h   ! [m] 2^40 boxes from the origin

  call grid%init(h, 4, err)
  call check(.not. err%failed(), 'init')

  ! 1: the planet, centre (0, 0, -big), top at z = 0; 2: a dust grain 1e-3 m above it
  call grid%place(1, [-big, -big, -2.0_dp*big], [big, big, 1.0e-10_dp], err)
  call check(.not. err%failed(), 'place the planet')
  call check(all(grid%lo(:, 1) == [-5000000000_i8, -5000000000_i8, -10000000000_i8]), &
             'the planet''s lower box is floor(lower/h) in 64 bits (no 32-bit overflow)')
  call check(all(grid%hi(:, 1) >= grid%lo(:, 1)), 'the planet''s box range is not empty')
  call check(grid%large(1), 'the planet spans more than max_span boxes: kept as large')
  call grid%place(2, [-2.0e-6_dp, -2.0e-6_dp, 0.998e-3_dp], [2.0e-6_dp, 2.0e-6_dp, 1.004e-3_dp], err)
  call check(.not. grid%large(2), 'the dust grain is listed in boxes')
  call grid%query(2, found, n_found, 4)
  call check(n_found == 0, 'the grain 1e-3 m above the planet''s region: no candidate')
  ! moved down to within its margin of the top
  call grid%place(2, [-2.0e-6_dp, -2.0e-6_dp, -1.0e-6_dp], [2.0e-6_dp, 2.0e-6_dp, 3.0e-6_dp], err)
  call grid%query(2, found, n_found, 4)
  call check(n_found == 1, 'the grain at the planet''s top finds one candidate')
  if (n_found == 1) call check(found(1) == 1, 'the grain finds the planet')
  call grid%query(1, found, n_found, 4)
  call check(n_found == 1, 'the planet (large) finds the grain')
  if (n_found == 1) call check(found(1) == 2, 'the planet finds the grain, by index')

  ! 3 and 4: two grains touching 2^40 boxes from the origin (box keys whose hash
  ! products would overflow int64 without the mask), 5: one a box further on
  call grid%place(3, [far, far, far], [far + 2.0e-6_dp, far + 2.0e-6_dp, far + 2.0e-6_dp], err)
  call grid%place(4, [far + 1.0e-6_dp, far, far], [far + 3.0e-6_dp, far + 2.0e-6_dp, far + 2.0e-6_dp], err)
  call check(.not. err%failed(), 'place grains 2^40 boxes out')
  call check(.not. (grid%large(3) .or. grid%large(4)), 'the far grains are listed in boxes')
  call grid%query(3, found, n_found, 4)
  call check(n_found == 1, 'a far grain finds one candidate')
  if (n_found == 1) call check(found(1) == 4, 'a far grain finds its neighbour')
  call grid%unplace(4)
  call grid%query(3, found, n_found, 4)
  call check(n_found == 0, 'an unplaced neighbour is gone')

  ! past 2^60 boxes: refused, not wrapped
  call grid%place(4, [2.0_dp**61*h, 0.0_dp, 0.0_dp], [2.0_dp**61*h + h, h, h], err)
  call check(err%failed(), 'a region 2^61 boxes out is refused')
  call grid%free()
  call test_finish()
end program test_cell_grid
