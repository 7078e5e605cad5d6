/* Private: a memo of a deterministic function of up to SB_MEMO_KEY
 * doubles to three doubles and a small state (memo.c).  Thread-safe
 * without a lock (a value being stored by another thread is a miss), of
 * fixed capacity: once 3/4 full it stops storing and answers what it
 * holds.  Keys compare bit for bit, so a hit returns the very values
 * stored. */
#ifndef SEPBRDF_MEMO_H
#define SEPBRDF_MEMO_H

#include <stddef.h>

#define SB_MEMO_KEY 6

typedef struct sb_memo sb_memo_t;

/* A memo of cap slots (rounded up to a power of two; 8 bytes a slot, and
 * 80 an entry for each value stored, the entries' pages touched as used);
 * NULL on no memory. */
sb_memo_t *sb_memo_create(size_t cap);
void sb_memo_destroy(sb_memo_t *m);
/* The state stored for key (0: none), its values in val. */
int sb_memo_find(sb_memo_t *m, const double key[SB_MEMO_KEY], double val[3]);
/* Store state (> 0) and val for key, unless the memo is full or already
 * holds the key. */
void sb_memo_store(sb_memo_t *m, const double key[SB_MEMO_KEY], const double val[3], int state);

#endif
