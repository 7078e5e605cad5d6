/* Private: what scene_mass.c needs of a scene beyond scene.h. */
#ifndef SEPBRDF_OUTPUT_SCENE_IMPL_H
#define SEPBRDF_OUTPUT_SCENE_IMPL_H

#include "sepbrdf/scene.h"

/* A ranges scene's density at the pair (wi, wo), per solid angle of each:
 * 1 / (4 pi^2 (cos a - cos b) (cos c - cos d)) for theta_o within view =
 * a..b and theta_i within light = c..d (sb_scene_draw's uniform draw), 0
 * outside them or for another kind. */
double sb_scene_ranges_pdf_(const sb_scene_t *s, const double wi[3], const double wo[3]);

#endif
