/* x (finite, > 0) to 21 significant decimal digits, correctly rounded, as "d.ddd...e+xx"
 * (namelist_source's real_text). glibc's printf is exact for %e at any precision, as
 * gfortran's ES edit descriptor is (it calls the same printf internally); called directly it
 * spares the formatted-I/O machinery, which was most of the cost of writing the effective
 * deck of 100,000 bodies. Returns the length written, or -1. */
#include <stdio.h>

int ricochet_decimal_digits21(double x, char *buffer, int size) {
  int n = snprintf(buffer, (size_t)size, "%.20e", x);
  if (n < 0 || n >= size) return -1;
  return n;
}
