/* sepbrdf-mpi batch: the materials of a batch over MPI ranks (built only
 * when CMake finds MPI; the plain sepbrdf has none of it).
 *
 * Every rank reads the same command line and so lists the same materials.
 * Rank 0 hands them out one at a time (a work queue: a rank that finishes
 * gets the next, so slow materials do not hold up the others), collects
 * each result line and alone writes the summary; the other ranks factor
 * the materials they are given into OUT/NAME, published whole as in a
 * single-process batch, so the layout and the bits are the same.  With
 * one rank, rank 0 runs the single-process batch itself. */
#ifdef SEPBRDF_MPI
#include <mpi.h>
#include <stdlib.h>
#include <string.h>

#include "batch.h"

enum { TAG_READY = 1, TAG_RESULT = 2, TAG_WORK = 3 };

int batch_mpi_begin(int *rank, int *size) {
    *size = 0;
    if (MPI_Init(NULL, NULL) != MPI_SUCCESS) return -1;
    MPI_Comm_rank(MPI_COMM_WORLD, rank);
    MPI_Comm_size(MPI_COMM_WORLD, size);
    return 0;
}

void batch_mpi_end(void) { MPI_Finalize(); }

/* Rank 0: answer every request with the next item not done, or -1 when
 * none is left; a request after a result carries the result line. */
static void hand_out(batch_item_t *items, size_t n, int size) {
    int *given = calloc((size_t)size, sizeof *given), left = size - 1;
    size_t next = 0, todo = 0, done = 0, failed = 0;
    for (size_t i = 0; i < n; i++)
        todo += !items[i].skipped;
    char line[BATCH_LINE];
    while (left > 0 && given) {
        MPI_Status st;
        MPI_Recv(line, BATCH_LINE, MPI_CHAR, MPI_ANY_SOURCE, MPI_ANY_TAG, MPI_COMM_WORLD, &st);
        int src = st.MPI_SOURCE;
        if (st.MPI_TAG == TAG_RESULT) {
            line[BATCH_LINE - 1] = 0;
            batch_item_t *it = &items[given[src]];
            if (!batch_take(it, line)) snprintf(it->msg, sizeof it->msg, "rank %d sent no result", src);
            failed += !it->ok;
            char label[64];
            snprintf(label, sizeof label, "batch %zu/%zu%s", ++done, todo, failed ? " (failed)" : "");
            cli_progress(label, (double)done / (double)todo);
        }
        while (next < n && items[next].skipped)
            next++;
        int idx = next < n ? (int)next++ : -1;
        if (idx >= 0) given[src] = idx;
        left -= idx < 0;
        MPI_Send(&idx, 1, MPI_INT, src, TAG_WORK, MPI_COMM_WORLD);
    }
    cli_progress_done();
    free(given);
}

/* A worker rank: ask, factor, answer, until told -1. */
static void take_work(const char *dir, batch_item_t *items, size_t n) {
    char line[BATCH_LINE] = "";
    MPI_Send(line, 1, MPI_CHAR, 0, TAG_READY, MPI_COMM_WORLD);
    for (;;) {
        int idx = -1;
        MPI_Recv(&idx, 1, MPI_INT, 0, TAG_WORK, MPI_COMM_WORLD, MPI_STATUS_IGNORE);
        if (idx < 0 || (size_t)idx >= n) return;
        batch_work(dir, &items[idx], line, sizeof line);
        MPI_Send(line, (int)strlen(line) + 1, MPI_CHAR, 0, TAG_RESULT, MPI_COMM_WORLD);
    }
}

void batch_mpi_run(const char *dir, batch_item_t *items, size_t n, size_t jobs, int rank, int size) {
    if (size < 2) {
        batch_run(dir, items, n, jobs);
        return;
    }
    if (rank == 0) {
        hand_out(items, n, size);
    } else {
        g_verbosity = g_verbosity > 0 ? 0 : g_verbosity; /* rank 0 reports */
        take_work(dir, items, n);
    }
}
#endif
