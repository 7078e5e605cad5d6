/* sepbrdf-mpi factor --method stream: the passes of the streamed solver
 * over MPI ranks (built only when CMake finds MPI).
 *
 * Every rank runs the same factor job on a context whose group
 * (common.h, sb_context_set_group) is MPI_COMM_WORLD: each evaluates
 * every size-th block of columns from the source, and the partial
 * products are summed by MPI_Reduce to rank 0 and MPI_Bcast, so every
 * rank holds the same bits and takes the same steps; rank 0 alone writes
 * the output set and reports.  A rank whose job fails aborts them all
 * (the others would wait for it in the next sum). */
#ifdef SEPBRDF_MPI
#include <mpi.h>

#include "batch.h"

/* The group's reduce: element-wise sum or maximum over the ranks, the
 * result on every rank (reduce to 0, then broadcast: the same bits). */
static int mpi_reduce(void *user, double *buf, size_t n, int op) {
    (void)user;
    int rank = 0;
    MPI_Comm_rank(MPI_COMM_WORLD, &rank);
    MPI_Op mop = op == SB_REDUCE_MAX ? MPI_MAX : MPI_SUM;
    const size_t chunk = (size_t)1 << 26; /* MPI counts are int */
    for (size_t i = 0; i < n; i += chunk) {
        int k = (int)(n - i < chunk ? n - i : chunk);
        void *send = rank == 0 ? MPI_IN_PLACE : buf + i;
        if (MPI_Reduce(send, buf + i, k, MPI_DOUBLE, mop, 0, MPI_COMM_WORLD) != MPI_SUCCESS ||
            MPI_Bcast(buf + i, k, MPI_DOUBLE, 0, MPI_COMM_WORLD) != MPI_SUCCESS)
            return -1;
    }
    return 0;
}

int factor_mpi_begin(sb_context_t *ctx, const sb_job_opts_t *o, int *rank, int *size) {
    if (batch_mpi_begin(rank, size) != 0) {
        cli_error("factor", "MPI_Init failed");
        return EXIT_IO;
    }
    if (*rank != 0) g_verbosity = g_verbosity > 0 ? 0 : g_verbosity; /* rank 0 reports */
    if (*size < 2) return EXIT_OK;
    if (o->method != SB_METHOD_STREAM) {
        if (*rank == 0)
            cli_error("factor",
                      "over %d MPI ranks only --method stream is shared out; run other methods with one "
                      "rank (or `sepbrdf factor`)",
                      *size);
        return EXIT_USAGE;
    }
    sb_group_t g = {*rank, *size, mpi_reduce, NULL};
    return sb_context_set_group(ctx, &g) == SB_OK ? EXIT_OK : EXIT_IO;
}

void factor_mpi_end(int size, int job_failed, int rc) {
    if (size > 1 && job_failed) MPI_Abort(MPI_COMM_WORLD, rc);
    if (size > 0) MPI_Finalize();
}
#endif
