/* Private: the estimator's mixture for wo given wi (estimate.h), for
 * draws of pairs over another distribution of wi (job_bandpairs.c), and
 * the whole domain's pair mixture for draws masked to a part of it (a
 * --theta-max cap, job_scene.c; a scene's ranges, scene_mass.c). */
#ifndef SEPBRDF_FACTOR_ESTIMATE_DRAW_H
#define SEPBRDF_FACTOR_ESTIMATE_DRAW_H

/* wo drawn from the point x of [0,1)^3 given wi (both unit, local frame):
 * uniform, cosine, four GGX lobes of the half vector around the normal
 * (wo = reflect(wi, h)) and the grazing density; returns its density
 * p_o(wo | wi), 0 when wi or wo is below the horizon. */
double sb_estimate_draw_wo(const double wi[3], const double x[3], double wo[3]);

/* The whole domain's pair (wi, wo) drawn from the point x of [0,1)^6 as
 * the estimator draws it (uniform, cosine and grazing wi; wo as above);
 * returns its density, 0 below the horizon.  Masked to a --theta-max cap
 * (job_scene.c), it measures within the cap with the mixture's draws
 * toward the lobe: uniform draws there read a sharp residual low. */
double sb_estimate_draw_pair(const double x[6], double wi[3], double wo[3]);

/* The density sb_estimate_draw_pair draws the pair (wi, wo) with, at any
 * pair (per solid angle of wi and of wo): what a draw that mixes it with
 * another (a scene's ranges, scene_mass.c) weighs each pair by; 0 below
 * the horizon. */
double sb_estimate_pair_pdf(const double wi[3], const double wo[3]);

/* wi drawn from x (three points of [0,1)) by the whole domain's mixture
 * for wi; returns its density (per solid angle). */
double sb_estimate_draw_wi(const double x[3], double wi[3]);
/* The density sb_estimate_draw_wi draws wi with; 0 below the horizon. */
double sb_estimate_wi_pdf(const double wi[3]);
/* The density sb_estimate_draw_wo draws wo with given wi (per solid
 * angle); 0 below the horizon. */
double sb_estimate_wo_pdf(const double wi[3], const double wo[3]);

/* The unit direction at cos theta = z, azimuth 2 pi u. */
void sb_estimate_dir_z(double z, double u, double w[3]);

#endif
