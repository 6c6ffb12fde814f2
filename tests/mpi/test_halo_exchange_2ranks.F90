! ctest-ranks: 2
!> test_halo_exchange on two ranks (dims 2x1x1, 1x2x1, 1x1x2): the same program, whose
!> cases follow the number of ranks.
#include "test_halo_exchange.F90"
