/* sepbrdf batch: the materials of a batch and how they are run. */
#ifndef SEPBRDF_CLI_BATCH_H
#define SEPBRDF_CLI_BATCH_H

#include "cli.h"

/* Result fields of one material, in the order of summary.csv after name
 * and source (batch.txt in its folder holds them, tab-separated). */
#define BATCH_FIELDS "param,form,J,headline,comparable,rel_rms,max_abs,negative,bytes,time_s"

typedef struct batch_item {
    char name[128]; /* its folder under --out */
    char source[1024];
    char param[2048], form[16]; /* storage of the row's --param (a whole layout spec too) and --form */
    sb_job_opts_t o;
    char key[1600];   /* its settings: the set is reused when they match */
    char fields[512]; /* BATCH_FIELDS, tab-separated */
    char msg[512];    /* why it failed */
    int ok, skipped;
    double headline;
} batch_item_t;

/* Settings key of item (from it->o) into it->key. */
void batch_key(batch_item_t *it);
/* 1 when DIR/NAME holds a published set of the same settings (its fields
 * copied into it->fields). */
int batch_done(const char *dir, batch_item_t *it);
/* Longest result line of one material. */
#define BATCH_LINE 1024

/* Factor item `it` into DIR/NAME (in this process) and write its result
 * line, "ok\tFIELDS" or "error\tMESSAGE", into line; the exit code. */
int batch_work(const char *dir, batch_item_t *it, char *line, size_t size);
/* Read a result line into it (ok, fields, headline or msg); 0 when the
 * line is neither. */
int batch_take(batch_item_t *it, const char *line);

/* Run the items not done with up to `jobs` processes at a time; fills
 * ok, fields and msg of each. */
void batch_run(const char *dir, batch_item_t *items, size_t n, size_t jobs);
/* sepbrdf-mpi (SEPBRDF_MPI, batch_mpi.c): MPI_Init and this process's
 * rank and the number of ranks (-1: MPI failed); MPI_Finalize; the items
 * over the ranks (one rank: batch_run with `jobs`), results on rank 0. */
int batch_mpi_begin(int *rank, int *size);
void batch_mpi_end(void);
void batch_mpi_run(const char *dir, batch_item_t *items, size_t n, size_t jobs, int rank, int size);
/* sepbrdf-mpi factor (factor_mpi.c): MPI_Init; over several ranks, the
 * group of ctx (the streamed passes shared out, --method stream only:
 * EXIT_USAGE otherwise) and quiet ranks but 0; an exit code.  End: a job
 * that failed on a rank aborts every rank, else MPI_Finalize. */
int factor_mpi_begin(sb_context_t *ctx, const sb_job_opts_t *o, int *rank, int *size);
void factor_mpi_end(int size, int job_failed, int rc);

/* Write DIR/summary.csv and DIR/summary.json; exit code. */
int batch_summary(const char *dir, const batch_item_t *items, size_t n);
/* The ranked table on stdout. */
void batch_table(const batch_item_t *items, size_t n);

#endif
