/* Whole-file reading and atomic writing.
 *
 * Writers never leave a partial file: output goes to a hidden temporary
 * ".NAME.tmp-XXXXXX" created by mkstemp in the destination's folder (same
 * file system, so rename(2) is atomic), every write error is caught by
 * checking fflush, ferror and fclose, and only then is the temporary renamed
 * over the destination. On failure or abort the temporary is removed and the
 * destination is left as it was. The new file gets the usual permissions
 * (0666 minus the umask), not mkstemp's 0600. */
#include "io/io.h"

#include <errno.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/stat.h>
#include <unistd.h>

/* stdio buffer for output files: large sequential writes. */
#define OUT_BUFFER (1u << 20)

static char *dup_string(const char *s)
{
    size_t n = strlen(s) + 1;
    char *d = malloc(n);
    if (d)
        memcpy(d, s, n);
    return d;
}

/* The process umask without changing it (umask(2) can only set it, which
 * would race with other threads): Linux reports it in /proc. */
static mode_t current_umask(void)
{
    mode_t mask = 022;
    FILE *f = fopen("/proc/self/status", "r");
    if (!f)
        return mask;
    char line[256];
    while (fgets(line, sizeof line, f)) {
        if (strncmp(line, "Umask:", 6) == 0) {
            mask = (mode_t)strtoul(line + 6, NULL, 8);
            break;
        }
    }
    fclose(f);
    return mask;
}

tessel_status tsl_outfile_open(tsl_outfile *out, const char *path, tessel_diag *diag)
{
    memset(out, 0, sizeof *out);
    if (!path || !*path) {
        tsl_diag_set(diag, "", 0, 0, 0, "no output path given");
        return TESSEL_ERR_INVALID_ARG;
    }
    const char *slash = strrchr(path, '/');
    size_t dir_len = slash ? (size_t)(slash - path) + 1 : 0;
    const char *base = slash ? slash + 1 : path;
    if (!*base) {
        tsl_diag_set(diag, path, 0, 0, 0, "output path names a folder, not a file");
        return TESSEL_ERR_IO;
    }
    size_t tmp_len = dir_len + 1 + strlen(base) + sizeof ".tmp-XXXXXX";
    out->path = dup_string(path);
    out->tmp_path = malloc(tmp_len);
    if (!out->path || !out->tmp_path) {
        free(out->path);
        free(out->tmp_path);
        memset(out, 0, sizeof *out);
        return TESSEL_ERR_NOMEM;
    }
    snprintf(out->tmp_path, tmp_len, "%.*s.%s.tmp-XXXXXX", (int)dir_len, path, base);
    int fd = mkstemp(out->tmp_path);
    if (fd < 0) {
        int err = errno;
        tsl_diag_set(diag, path, 0, 0, 0, "cannot create a file in %s: %s",
                     dir_len ? "its folder" : "the current folder", strerror(err));
        free(out->path);
        free(out->tmp_path);
        memset(out, 0, sizeof *out);
        return TESSEL_ERR_IO;
    }
    /* Keep an existing destination's mode; new files get 0666 & ~umask. */
    struct stat st;
    mode_t mode = (stat(path, &st) == 0 && S_ISREG(st.st_mode))
                      ? (st.st_mode & 07777)
                      : (0666 & ~current_umask());
    (void)fchmod(fd, mode); /* best effort: mkstemp's 0600 is still safe */
    out->fp = fdopen(fd, "wb");
    if (!out->fp) {
        int err = errno;
        close(fd);
        unlink(out->tmp_path);
        tsl_diag_set(diag, path, 0, 0, 0, "cannot open for writing: %s", strerror(err));
        free(out->path);
        free(out->tmp_path);
        memset(out, 0, sizeof *out);
        return TESSEL_ERR_IO;
    }
    setvbuf(out->fp, NULL, _IOFBF, OUT_BUFFER);
    return TESSEL_OK;
}

static void outfile_release(tsl_outfile *out)
{
    free(out->path);
    free(out->tmp_path);
    memset(out, 0, sizeof *out);
}

tessel_status tsl_outfile_commit(tsl_outfile *out, tessel_diag *diag)
{
    if (!out->fp)
        return TESSEL_ERR_INVALID_ARG;
    int err = 0;
    errno = 0;
    if (fflush(out->fp) != 0 || ferror(out->fp))
        err = errno ? errno : EIO;
    if (fclose(out->fp) != 0 && !err)
        err = errno ? errno : EIO;
    out->fp = NULL;
    if (!err && rename(out->tmp_path, out->path) != 0)
        err = errno;
    if (err) {
        unlink(out->tmp_path);
        tsl_diag_set(diag, out->path, 0, 0, 0, "write failed: %s", strerror(err));
        outfile_release(out);
        return TESSEL_ERR_IO;
    }
    outfile_release(out);
    return TESSEL_OK;
}

void tsl_outfile_abort(tsl_outfile *out)
{
    if (!out)
        return;
    if (out->fp) {
        fclose(out->fp);
        out->fp = NULL;
    }
    if (out->tmp_path)
        unlink(out->tmp_path);
    outfile_release(out);
}

/* ---- reading ---- */

tessel_status tsl_read_file(const char *path, uint8_t **data, size_t *size,
                            tessel_diag *diag)
{
    *data = NULL;
    *size = 0;
    if (!path || !*path) {
        tsl_diag_set(diag, "", 0, 0, 0, "no input path given");
        return TESSEL_ERR_INVALID_ARG;
    }
    FILE *f = fopen(path, "rb");
    if (!f) {
        int err = errno;
        tsl_diag_set(diag, path, 0, 0, 0, "cannot open: %s", strerror(err));
        return TESSEL_ERR_IO;
    }
    struct stat st;
    if (fstat(fileno(f), &st) != 0) {
        int err = errno;
        fclose(f);
        tsl_diag_set(diag, path, 0, 0, 0, "cannot stat: %s", strerror(err));
        return TESSEL_ERR_IO;
    }
    if (S_ISDIR(st.st_mode)) {
        fclose(f);
        tsl_diag_set(diag, path, 0, 0, 0, "is a folder, not a file");
        return TESSEL_ERR_IO;
    }
    /* Regular files: one read of the known size. Pipes and devices: grow. */
    size_t cap = S_ISREG(st.st_mode) ? (size_t)st.st_size + 1 : (size_t)1 << 16;
    if (S_ISREG(st.st_mode) && (uint64_t)st.st_size >= SIZE_MAX) {
        fclose(f);
        tsl_diag_set(diag, path, 0, 0, 0, "file too large for this machine");
        return TESSEL_ERR_LIMIT;
    }
    uint8_t *buf = tsl_alloc_array(cap, 1); /* huge pages for a large file */
    if (!buf) {
        fclose(f);
        tsl_diag_set(diag, path, 0, 0, 0, "out of memory reading %llu bytes",
                     (unsigned long long)cap);
        return TESSEL_ERR_NOMEM;
    }
    size_t n = 0;
    for (;;) {
        if (n + 1 >= cap) {
            /* Full (the usual case for a regular file): grow only if there
             * really is more, so reading a file costs its size once. */
            int c = fgetc(f);
            if (c == EOF) {
                if (ferror(f)) {
                    int err = errno;
                    free(buf);
                    fclose(f);
                    tsl_diag_set(diag, path, 0, 1, n, "read error: %s",
                                 strerror(err ? err : EIO));
                    return TESSEL_ERR_IO;
                }
                break;
            }
            if (cap > SIZE_MAX / 2) {
                free(buf);
                fclose(f);
                tsl_diag_set(diag, path, 0, 0, 0, "file too large for this machine");
                return TESSEL_ERR_LIMIT;
            }
            if (tsl_resize((void **)&buf, n, cap * 2)) {
                free(buf);
                fclose(f);
                tsl_diag_set(diag, path, 0, 0, 0, "out of memory reading the file");
                return TESSEL_ERR_NOMEM;
            }
            cap *= 2;
            buf[n++] = (uint8_t)c;
        }
        size_t got = fread(buf + n, 1, cap - 1 - n, f);
        n += got;
        if (got == 0) {
            if (ferror(f)) {
                int err = errno;
                free(buf);
                fclose(f);
                tsl_diag_set(diag, path, 0, 1, n, "read error: %s",
                             strerror(err ? err : EIO));
                return TESSEL_ERR_IO;
            }
            break; /* end of file */
        }
    }
    fclose(f);
    buf[n] = 0;
    *data = buf;
    *size = n;
    return TESSEL_OK;
}
