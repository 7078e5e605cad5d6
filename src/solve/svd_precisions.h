/* Includes the precision template named by SB_SVD_TEMPLATE twice: with
 *     R = double, SFX = d, and the d-prefixed BLAS/LAPACK routines (GEMM_THIN:
 *     the library's threaded product of a large matrix with a thin block), then
 *     R = float,  SFX = f, and the s-prefixed ones.
 * Not a header of its own: no guard. */

#define R double
#define SFX d
#define GEMM cblas_dgemm
#define GEMM_THIN sb_dgemm_thin
#define SYRK cblas_dsyrk
#define GESDD LAPACKE_dgesdd_work
#define SYEVR LAPACKE_dsyevr_work
#define GEQRF LAPACKE_dgeqrf_work
#define ORGQR LAPACKE_dorgqr_work
#define ORMQR LAPACKE_dormqr_work
#include SB_SVD_TEMPLATE
#undef R
#undef SFX
#undef GEMM
#undef GEMM_THIN
#undef SYRK
#undef GESDD
#undef SYEVR
#undef GEQRF
#undef ORGQR
#undef ORMQR

#define R float
#define SFX f
#define GEMM cblas_sgemm
#define GEMM_THIN sb_sgemm_thin
#define SYRK cblas_ssyrk
#define GESDD LAPACKE_sgesdd_work
#define SYEVR LAPACKE_ssyevr_work
#define GEQRF LAPACKE_sgeqrf_work
#define ORGQR LAPACKE_sorgqr_work
#define ORMQR LAPACKE_sormqr_work
#include SB_SVD_TEMPLATE
#undef R
#undef SFX
#undef GEMM
#undef GEMM_THIN
#undef SYRK
#undef GESDD
#undef SYEVR
#undef GEQRF
#undef ORGQR
#undef ORMQR
