/* Includes the precision template named by SB_SVD_TEMPLATE twice: with
 *     R = double, SFX = d, and the d-prefixed BLAS/LAPACK routines, then
 *     R = float,  SFX = f, and the s-prefixed ones.
 * Not a header of its own: no guard. */

#define R double
#define SFX d
#define GEMM cblas_dgemm
#define SYRK cblas_dsyrk
#define GESDD LAPACKE_dgesdd_work
#define SYEVR LAPACKE_dsyevr_work
#define GEQRF LAPACKE_dgeqrf_work
#define ORGQR LAPACKE_dorgqr_work
#include SB_SVD_TEMPLATE
#undef R
#undef SFX
#undef GEMM
#undef SYRK
#undef GESDD
#undef SYEVR
#undef GEQRF
#undef ORGQR

#define R float
#define SFX f
#define GEMM cblas_sgemm
#define SYRK cblas_ssyrk
#define GESDD LAPACKE_sgesdd_work
#define SYEVR LAPACKE_ssyevr_work
#define GEQRF LAPACKE_sgeqrf_work
#define ORGQR LAPACKE_sorgqr_work
#include SB_SVD_TEMPLATE
#undef R
#undef SFX
#undef GEMM
#undef SYRK
#undef GESDD
#undef SYEVR
#undef GEQRF
#undef ORGQR
