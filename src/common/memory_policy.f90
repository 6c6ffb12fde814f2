!> How the process's C allocator hands out and takes back memory (memory_policy.c): large
!> blocks from the heap, freed memory kept for the next block, so that arrays rebuilt at
!> every window do not cost page faults each time. Set once by the driver, before the run.
module memory_policy
  use, intrinsic :: iso_c_binding, only: c_int
  implicit none
  private
  public :: keep_freed_memory

  interface
    integer(c_int) function c_keep_freed_memory() bind(c, name='ricochet_keep_freed_memory')
      import :: c_int
    end function c_keep_freed_memory
  end interface

contains

  !> Whether the policy was set (false where the C library has no such control: nothing
  !> changes then but the time).
  logical function keep_freed_memory()
    keep_freed_memory = c_keep_freed_memory() == 1
  end function keep_freed_memory

end module memory_policy
