/* The analytic lobe of the sampler's mixture (sepbrdf/sampler.h): a GGX
 * (Trowbridge-Reitz) distribution of normals about the surface normal,
 * isotropic with roughness alpha, sampled through its visible normals
 * (Heitz 2018, "Sampling the GGX Distribution of Visible Normals", JCGT
 * 7(4)) and the light reflected about them.
 *
 * With the visible normals D_V(h) = G1(wo) max(0, wo.h) D(h) / wo.z of
 * Smith's G1(wo) = 2 wo.z / (wo.z + sqrt(alpha^2 (wo.x^2 + wo.y^2) +
 * wo.z^2)) and D(h) = 1 / (pi alpha^2 k^2), k = (h.x^2 + h.y^2) / alpha^2 +
 * h.z^2 (h.z > 0), the density of wi = reflect(wo, h) is
 *     p_lobe(wi) = D_V(h) / (4 wo.h) = D(h) / (2 (wo.z + sqrt(alpha^2
 *                  (wo.x^2 + wo.y^2) + wo.z^2)))
 * with h = (wi + wo) / |wi + wo|.  It integrates to 1 over the sphere of
 * wi; the wi below the horizon (or outside the layout's domain) are
 * failed samples, as in the factored component of the half-vector
 * layouts.  The GLSL's sb_lobe_dir and sb_lobe_pdf
 * (data/sepbrdf_sample.glsl) repeat these steps in float. */
#include <math.h>

#include "sampler_impl.h"

int sb_lobe_dir_(double alpha, const double wo[3], double u0, double u1, double wi[3]) {
    if (!(wo[2] > 0)) return 0;
    /* the view in the hemisphere configuration (alpha = 1) */
    double v[3] = {alpha * wo[0], alpha * wo[1], wo[2]}, n = sqrt(v[0] * v[0] + v[1] * v[1] + v[2] * v[2]);
    for (int i = 0; i < 3; i++)
        v[i] /= n;
    double len2 = v[0] * v[0] + v[1] * v[1], t1v[3] = {1, 0, 0};
    if (len2 > 0) {
        double l = sqrt(len2);
        t1v[0] = -v[1] / l, t1v[1] = v[0] / l;
    }
    double t2v[3] = {v[1] * t1v[2] - v[2] * t1v[1], v[2] * t1v[0] - v[0] * t1v[2], v[0] * t1v[1] - v[1] * t1v[0]};
    /* a point of the disk, its lower half squeezed by the projection of the view */
    double r = sqrt(u0), phi = 2 * SB_PI * u1, t1 = r * cos(phi), t2 = r * sin(phi), s = 0.5 * (1 + v[2]);
    t2 = (1 - s) * sqrt(fmax(1 - t1 * t1, 0)) + s * t2;
    double t3 = sqrt(fmax(1 - t1 * t1 - t2 * t2, 0)), m[3];
    for (int i = 0; i < 3; i++)
        m[i] = t1 * t1v[i] + t2 * t2v[i] + t3 * v[i];
    /* back to the ellipsoid configuration: the normal h */
    double h[3] = {alpha * m[0], alpha * m[1], fmax(m[2], 0)};
    n = sqrt(h[0] * h[0] + h[1] * h[1] + h[2] * h[2]);
    if (!(n > 0)) return 0;
    double d = (h[0] * wo[0] + h[1] * wo[1] + h[2] * wo[2]) / n;
    for (int i = 0; i < 3; i++)
        wi[i] = 2 * d * h[i] / n - wo[i];
    return 1;
}

double sb_lobe_pdf_(double alpha, const double wo[3], const double wi[3]) {
    double h[3] = {wi[0] + wo[0], wi[1] + wo[1], wi[2] + wo[2]};
    double n2 = h[0] * h[0] + h[1] * h[1] + h[2] * h[2];
    if (!(wo[2] > 0) || !(h[2] > 0) || !(n2 > 0)) return 0;
    if (!(h[0] * wo[0] + h[1] * wo[1] + h[2] * wo[2] > 0)) return 0;
    /* k = ((h.x^2 + h.y^2) / alpha^2 + h.z^2) / |h|^2 for the unnormalised h */
    double a2 = alpha * alpha, k = ((h[0] * h[0] + h[1] * h[1]) / a2 + h[2] * h[2]) / n2;
    double d = 1 / (SB_PI * a2 * k * k);
    return d / (2 * (wo[2] + sqrt(a2 * (wo[0] * wo[0] + wo[1] * wo[1]) + wo[2] * wo[2])));
}
