/* sepbrdf: result codes, the context and small shared helpers.
 *
 * Every library function returns an sb_result_t (SB_OK == 0).  Details of a
 * failure ("theta count 0, need at least 2") go to the error callback of the
 * context and are kept as its last message; the library never prints, exits
 * or aborts on bad input.
 *
 * Misuse is answered, never crashed on: a NULL handle or output, a size of
 * 0 or SIZE_MAX, an index out of range or an unknown enum value gives
 * SB_ERR_ARG / SB_ERR_RANGE / SB_ERR_OVERFLOW from functions that return a
 * result code.  Getters that cannot return a code give a safe value
 * instead, the same everywhere unless their header says otherwise: 0 for
 * counts, sizes and flags, NaN for values (sigma, measures, texels), ""
 * for names and descriptions, NULL for other pointers, 0 ("not a pair",
 * "missing") for int predicates, and "?" for the name of an unknown enum
 * value; functions returning void then change nothing but zero the
 * outputs they were given. */
#ifndef SEPBRDF_COMMON_H
#define SEPBRDF_COMMON_H

#include <stddef.h>
#include <stdint.h>

#ifdef __cplusplus
extern "C" {
#endif

#define SB_VERSION_MAJOR 0
#define SB_VERSION_MINOR 1
#define SB_VERSION_PATCH 0
#define SB_VERSION_STRING "0.1.0"

/* SB_API marks every function of the public headers: the library is built
 * with hidden visibility (-fvisibility=hidden), so it exports these and
 * nothing else (scripts/check_exports.sh checks it). */
#if defined(__GNUC__) || defined(__clang__)
#define SB_API __attribute__((visibility("default")))
#else
#define SB_API
#endif

#define SB_PI 3.14159265358979323846

typedef enum sb_result {
    SB_OK = 0,
    SB_ERR_ARG,         /* invalid argument (NULL, bad enum, bad option value) */
    SB_ERR_RANGE,       /* a number outside its allowed range */
    SB_ERR_PARSE,       /* malformed text: model spec, number, table line */
    SB_ERR_UNKNOWN,     /* unknown model, key, preset or format */
    SB_ERR_NOMEM,       /* allocation failed */
    SB_ERR_OVERFLOW,    /* a size product overflows or exceeds the memory limit */
    SB_ERR_IO,          /* file could not be opened, read or written */
    SB_ERR_FORMAT,      /* file content is not what its format requires */
    SB_ERR_NUMERIC,     /* LAPACK failure, non-finite result */
    SB_ERR_UNSUPPORTED, /* valid request this build or combination cannot do */
    SB_RESULT_COUNT_
} sb_result_t;

/* The library's version at run time ("0.1.0"; the SB_VERSION_* macros
 * above are the headers' a program was compiled with), and as one number,
 * MAJOR * 10000 + MINOR * 100 + PATCH (as zstd's ZSTD_versionNumber). */
SB_API const char *sb_version(void);
SB_API unsigned sb_version_number(void);

/* Static name ("SB_ERR_RANGE") and one-line description of a code. */
SB_API const char *sb_result_name(sb_result_t r);
SB_API const char *sb_result_message(sb_result_t r);

typedef void (*sb_error_fn)(void *user, sb_result_t code, const char *message);

typedef struct sb_context sb_context_t;

/* Create a context.  The default callback does nothing; the last message is
 * always kept and readable with sb_context_last_error(). */
SB_API sb_result_t sb_context_create(sb_context_t **out);
SB_API void sb_context_destroy(sb_context_t *ctx); /* accepts NULL */
SB_API void sb_context_set_error_callback(sb_context_t *ctx, sb_error_fn fn, void *user);
/* Last detailed message, "" if none.  Owned by the context. */
SB_API const char *sb_context_last_error(const sb_context_t *ctx);
SB_API void sb_context_clear_error(sb_context_t *ctx);

/* A group of processes that share the passes of a streamed factorisation
 * (solver.h: the stream solver and the plan's residual pass over a
 * streamed matrix), e.g. MPI ranks.  Every process of the group runs the
 * same calls with a context holding its group; process `rank` of `size`
 * reads only the blocks of columns b with b mod size == rank and the
 * partial results are combined by `reduce`: element-wise over buf[0..n),
 * op SB_REDUCE_SUM or SB_REDUCE_MAX, and on return every process holds
 * the same bits (e.g. MPI_Reduce to one rank, then MPI_Bcast).  reduce
 * returns 0 on success.  The results equal those of one process to the
 * solver's tolerance (sums in another order), not bit for bit. */
enum { SB_REDUCE_SUM = 0, SB_REDUCE_MAX = 1 };
typedef struct sb_group {
    int rank, size;
    int (*reduce)(void *user, double *buf, size_t n, int op);
    void *user;
} sb_group_t;
/* Copy *group into ctx (NULL or size < 2: this process alone, the
 * default).  SB_ERR_ARG for a rank outside 0..size-1 or no reduce. */
SB_API sb_result_t sb_context_set_group(sb_context_t *ctx, const sb_group_t *group);

/* Report an error through the context (ctx may be NULL) and return `code`.
 * Used by every module; public so that sources written outside the library
 * can report in the same way. */
SB_API sb_result_t sb_error(sb_context_t *ctx, sb_result_t code, const char *fmt, ...)
#if defined(__GNUC__)
    __attribute__((format(printf, 3, 4)))
#endif
    ;

/* Allocation limit used for up-front refusal of huge requests (bytes).
 * Default: 3/4 of physical memory.  0 restores the default. */
SB_API void sb_set_memory_limit(size_t bytes);
SB_API size_t sb_memory_limit(void);

#ifdef __cplusplus
}
#endif
#endif
