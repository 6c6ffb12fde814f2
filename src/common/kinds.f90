!> Numeric kinds used everywhere: dp for all physics, i8 for counters that can pass 2^31.
module kinds
  use, intrinsic :: iso_fortran_env, only: real64, int32, int64
  implicit none
  private
  public :: dp, i4, i8
  integer, parameter :: dp = real64
  integer, parameter :: i4 = int32
  integer, parameter :: i8 = int64
end module kinds
