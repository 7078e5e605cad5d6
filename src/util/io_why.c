/* The wording of file errors (util/shared.h). */
#define _GNU_SOURCE
#include <errno.h>
#include <string.h>

#include "util/shared.h"

const char *sb_io_why(int err) {
    switch (err) {
    case ENOSPC:
        return "disk full (no space left on device)";
    case EDQUOT:
        return "disk quota exceeded";
    case EFBIG:
        return "file too large (the file size limit, ulimit -f, was reached)";
    case ENAMETOOLONG:
        return "name too long for the file system";
    default:
        return strerror(err);
    }
}
