/* Private: what scene_mass.c needs of a scene beyond scene.h. */
#ifndef SEPBRDF_OUTPUT_SCENE_IMPL_H
#define SEPBRDF_OUTPUT_SCENE_IMPL_H

#include "sepbrdf/scene.h"

/* A ranges scene's density at the pair (wi, wo), per solid angle of each:
 * 1 / (4 pi^2 (cos a - cos b) (cos c - cos d)) for theta_o within view =
 * a..b and theta_i within light = c..d (sb_scene_draw's uniform draw), 0
 * outside them or for another kind. */
double sb_scene_ranges_pdf_(const sb_scene_t *s, const double wi[3], const double wo[3]);

/* A lights scene's pair at the point (px, py) of the sphere's image lit by
 * light k (< sb_scene_light_count_): L and V in the frame of
 * sb_render_frame_at there, as sb_scene_draw maps them; 1 when lit (L.n >
 * 0), 0 when not, off the image (px^2 + py^2 >= 1), for k beyond the
 * lights or another kind. */
int sb_scene_light_pair_(const sb_scene_t *s, double px, double py, size_t k, double wi[3], double wo[3]);
/* The lights of a lights scene (0 for another kind), and the unit
 * direction of light k (world, towards the light; NULL beyond them). */
size_t sb_scene_light_count_(const sb_scene_t *s);
const double *sb_scene_light_dir_(const sb_scene_t *s, size_t k);

#endif
