!> Mathematical constants and fixed numerical thresholds that more than one module needs.
module constants
  use kinds, only: dp
  implicit none
  private
  public :: pi, two_pi, unit_quaternion_tolerance, name_length, path_length, line_length

  real(dp), parameter :: pi = 3.141592653589793238462643383279502884_dp
  real(dp), parameter :: two_pi = 2.0_dp*pi
  !> A quaternion from a deck is accepted as unit if | |q| - 1 | is below this; it is then
  !> renormalised. Larger deviations are input errors (a typo, not round-off).
  real(dp), parameter :: unit_quaternion_tolerance = 1.0e-6_dp
  integer, parameter :: name_length = 64
  integer, parameter :: path_length = 1024
  !> A line of text that may hold a path (effective deck lines, shape labels)
  integer, parameter :: line_length = path_length + 76
end module constants
