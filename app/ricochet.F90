!> The ricochet program: parse the command line, hand the deck to the library, report.
program ricochet
  use parallel_env, only: parallel_t
  implicit none
  type(parallel_t) :: par
  call par%init()
  if (par%is_root()) print '(a)', 'ricochet '//RICOCHET_VERSION
  call par%free()
end program ricochet
