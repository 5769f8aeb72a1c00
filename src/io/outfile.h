/* Output files that appear whole or not at all: the bytes go to a
 * temporary file in the destination's folder, which commit renames over
 * the destination (with the usual file mode) once everything was written
 * and flushed, and abort removes. The library's writers use it, and so
 * does the command-line tool for the files it writes itself (PNG); this
 * header is its whole interface, with no other part of src/io/. Not
 * installed. */
#ifndef TESSEL_IO_OUTFILE_H
#define TESSEL_IO_OUTFILE_H

#include "tessel.h"

#include <stdio.h>

typedef struct tsl_outfile {
    FILE *fp;       /* write here between open and commit / abort */
    char *path;
    char *tmp_path;
} tsl_outfile;

/* Creates the temporary beside path. On failure diag names the path. */
tessel_status tsl_outfile_open(tsl_outfile *out, const char *path, tessel_diag *diag);
/* Flushes, checks for write errors, closes and renames. On failure the
 * temporary is removed and diag names the path. */
tessel_status tsl_outfile_commit(tsl_outfile *out, tessel_diag *diag);
/* Closes and removes the temporary; the destination is untouched. */
void tsl_outfile_abort(tsl_outfile *out);

#endif /* TESSEL_IO_OUTFILE_H */
