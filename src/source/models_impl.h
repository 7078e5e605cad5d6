/* Private: the analytic models' parameters, shared by models.c (keys,
 * presets, spec parsing) and models_eval.c (the formulas). */
#ifndef SEPBRDF_MODELS_IMPL_H
#define SEPBRDF_MODELS_IMPL_H

enum { M_LAMBERT, M_PHONG, M_PHONG_GLSL, M_MPHONG, M_BLINN, M_NBLINN, M_CT, M_MICROFACET };
enum { D_GGX, D_BECKMANN, D_BECKMANN_NORM, D_GAUSSIAN };
enum { G_SMITH_SCHLICK, G_SMITH_DISNEY, G_SMITH_ALPHA, G_VCAVITY, G_NONE };
enum { F_SCHLICK, F_CONDUCTOR, F_DIELECTRIC, F_NONE };
enum { DENOM_4, DENOM_COS, DENOM_PI };
enum { NORM_RTR, NORM_EXACT };

/* Floor of a cosine in a denominator when guard = 0.  It keeps f finite for
 * every double input: the largest factor any model puts on such cosines is
 * D/(4 c^2) with D <= 1/(pi alpha^2) <= 3.2e11 (roughness >= 0.001), so
 * f < 1e212 at c = 1e-100.  1e-100 rad is far below any sampled angle, so
 * the clamp never changes a value anyone samples. */
#define SB_COS_FLOOR 1e-100

typedef struct model {
    int kind;
    double albedo[3], kd[3], ks[3];
    double n;        /* Phong / Blinn-Phong exponent */
    double rv_floor; /* modified Phong: floor of r.v (the lecture GLSL uses 0.001) */
    double guard;    /* floor of cosines in denominators (the lecture's 0.001) */
    int norm, d, g, f, denom;
    double roughness, f0[3], ior;
    double base[3], metallic, reflectance;
    double
        anisotropy; /* microfacet: 0 isotropic; alpha_x = alpha / a, alpha_y = alpha a, a = sqrt(1 - 0.9 anisotropy) */
    /* derived */
    double cmin;   /* guard, or SB_COS_FLOOR when guard = 0 */
    double cspec;  /* constant factor of the specular lobe */
    double alpha;  /* GGX alpha = roughness^2; Beckmann/Gaussian m = roughness */
    double ax, ay; /* microfacet: GGX widths along the tangent x and the bitangent y */
    double k;      /* Schlick-GGX k */
} model_t;

/* f_r of each model (self: its model_t), the source interface's eval. */
int sb_model_lambert_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_phong_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_phong_glsl_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_mphong_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_blinn_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_nblinn_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_ct_(const void *self, const double l[3], const double v[3], double rgb[3]);
int sb_model_microfacet_(const void *self, const double l[3], const double v[3], double rgb[3]);

#endif
