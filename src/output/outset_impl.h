/* Private to the output sets (outset.c, outset_paths.c). */
#ifndef SEPBRDF_OUTSET_IMPL_H
#define SEPBRDF_OUTSET_IMPL_H

#include "sepbrdf/outset.h"

#define STAGE_TAG ".sepbrdf-new-"
/* Longest name a set may add plus the staging suffix: what must fit. */
#define NAME_ROOM 64

/* "a/b", malloc'd; NULL on no memory. */
char *outset_join(const char *a, const char *b);
/* DIR (as the user gave it, `target`) -> PARENT and NAME, malloc'd:
 * trailing '/' dropped; ".", "..", "/" and symbolic links resolved through
 * realpath (they must exist then).  SB_ERR_IO for a name too long. */
sb_result_t outset_split(sb_context_t *ctx, const char *target, char **parent, char **base);
/* sb_outset_check on a split DIR: the checks of outset.h. */
sb_result_t outset_check_paths(sb_context_t *ctx, const char *target, const char *parent, const char *base);
/* An existing DIR = PARENT/NAME: not a mount point, not holding the
 * current folder, no subfolders. */
sb_result_t outset_check_existing(sb_context_t *ctx, const char *target, const char *dir, const char *parent);

#endif
