! ctest-ranks: 2
!> test_exact_sum_mpi on two ranks: the same program, whose splits follow the number of
!> ranks.
#include "test_exact_sum_mpi.F90"
