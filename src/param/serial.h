/* Private: the one thing layers above param/ ask of a layout that is not
 * public (param.c). */
#ifndef SEPBRDF_PARAM_SERIAL_H
#define SEPBRDF_PARAM_SERIAL_H

#include "sepbrdf/param.h"

/* A number that parameterisations created in this process share exactly
 * when their resolved layouts (kind, sizes, wraps, theta_max, warps) are
 * the same: the key of coordinates cached for it (the estimator's
 * pairs). */
unsigned long sb_param_serial_(const sb_param_t *p);

#endif
