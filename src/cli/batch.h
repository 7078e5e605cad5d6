/* sepbrdf batch: the materials of a batch and how they are run. */
#ifndef SEPBRDF_CLI_BATCH_H
#define SEPBRDF_CLI_BATCH_H

#include <stdint.h>

#include "cli.h"

/* Result fields of one material, in the order of summary.csv after name
 * and source (batch.txt in its folder holds them, tab-separated). */
#define BATCH_FIELDS "param,form,weighted,J,headline,comparable,rel_rms,max_abs,negative,bytes,time_s"
#define BATCH_NF 11 /* how many */

typedef struct batch_item {
    char name[256];     /* its folder under --out */
    const char *source; /* strings owned by the batch (argv, a manifest's text) */
    sb_job_opts_t o;
    char *key;     /* its settings (malloc): the set is reused when they match */
    char *fields;  /* BATCH_FIELDS, tab-separated, as its folder holds them (malloc; NULL: none) */
    char msg[512]; /* why it failed */
    int ok, skipped;
    int other; /* its folder holds a set of other settings (fields are that set's) */
    double headline;
} batch_item_t;

/* Lock folder DIR for this batch (refused, message printed, while another
 * batch or its workers hold it): the lock's descriptor, inherited by the
 * workers, or -1.  batch_unlock: this process's hold ends. */
int batch_lock(const char *dir);
void batch_unlock(int fd);
/* Settings key of item (from it->o) into it->key; -1 out of memory. */
int batch_key(batch_item_t *it);
/* What DIR/NAME holds: 1 and its key and fields (malloc'd) when a
 * published set with batch.txt, every file as batch.txt recorded it, else
 * 0 (both NULL; why, when not NULL, says what differs, "" where the
 * folder holds no set). */
int batch_folder_read(const char *dir, const char *name, char **key, char **fields, char *why, size_t wsize);
/* Line 3 of batch.txt to fp: the hash of head (lines 1-2, newlines
 * included), then the name, size and hash of every file in folder dir but
 * batch.txt; -1 when one cannot be read. */
/* FNV-1a (64 bits) of n bytes, continuing from h (BATCH_FNV_START to
 * begin): folder names' and batch.txt's sums. */
#define BATCH_FNV_START 0xcbf29ce484222325ull
uint64_t batch_fnv1a(uint64_t h, const void *data, size_t n);
int batch_sums_write(FILE *fp, const char *dir, const char *head);
/* 1 when DIR/NAME holds a published set of the same settings (its fields
 * copied into it->fields). */
int batch_done(const char *dir, batch_item_t *it);
/* After the run: fields, ok and headline of every item from what its
 * folder holds (a set of its settings: ok; another: other, fields of that
 * set; none: no fields). */
void batch_reread(const char *dir, batch_item_t *items, size_t n);
/* Longest result line of one material ("ok" or "error\tMESSAGE"). */
#define BATCH_LINE 1024
/* The file of a set that holds the key and fields. */
#define BATCH_FILE "batch.txt"

/* Factor item `it` into DIR/NAME (in this process) and write its result
 * line, "ok" or "error\tMESSAGE", into line; the exit code. */
int batch_work(const char *dir, batch_item_t *it, char *line, size_t size);
/* Read a result line into it (ok or msg; the fields are read from its
 * folder); 0 when the line is neither. */
int batch_take(batch_item_t *it, const char *line);

/* Run the items not done with up to `jobs` processes at a time; fills
 * ok and msg of each (the fields: batch_reread, from the folders). */
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

/* Remove DIR/summary.csv and DIR/summary.json before the run changes any
 * folder (an interrupted run then leaves no summary rather than one that
 * disagrees with the folders); exit code, message printed. */
int batch_summary_remove(const char *dir);
/* Write DIR/summary.csv and DIR/summary.json; exit code. */
int batch_summary(const char *dir, const batch_item_t *items, size_t n);
/* The ranked table on stdout. */
void batch_table(const batch_item_t *items, size_t n);

#endif
