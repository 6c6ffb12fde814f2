! ctest-ranks: 2
!> test_migration on two ranks (dims 2x1x1, 1x2x1, 1x1x2): the same program, whose cases
!> follow the number of ranks (no body two bricks away: every other rank is a neighbour).
#include "test_migration.F90"
