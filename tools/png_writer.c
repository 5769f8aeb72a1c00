/* PNG writer over libpng (see png_writer.h). libpng reports errors by longjmp to
 * the setjmp below; everything that must survive the jump is volatile or
 * set before it. */
#include "png_writer.h"

#include "io/outfile.h"

#include <png.h>
#include <setjmp.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

typedef struct png_failure {
    char *err;
    size_t errlen;
} png_failure;

static void on_png_error(png_structp png, png_const_charp msg)
{
    png_failure *f = png_get_error_ptr(png);
    snprintf(f->err, f->errlen, "%s", msg);
    png_longjmp(png, 1);
}

static void on_png_warning(png_structp png, png_const_charp msg)
{
    (void)png;
    (void)msg; /* warnings do not stop the write and are not worth a line */
}

int png_write_rgb(const char *path, const uint8_t *rgb, uint32_t width, uint32_t height,
                  char *err, size_t errlen)
{
    /* The library's safe-write helper: temporary next to the destination,
     * renamed only when everything was written, usual file mode. */
    tsl_outfile out;
    tessel_diag diag = {0};
    if (tsl_outfile_open(&out, path, &diag) != TESSEL_OK) {
        snprintf(err, errlen, "%s", diag.message);
        return -1;
    }
    png_failure failure = {err, errlen};
    png_structp png = png_create_write_struct(PNG_LIBPNG_VER_STRING, &failure, on_png_error,
                                              on_png_warning);
    png_infop info = png ? png_create_info_struct(png) : NULL;
    volatile int ok = 0;
    if (!png || !info) {
        snprintf(err, errlen, "out of memory");
    } else if (setjmp(png_jmpbuf(png)) == 0) {
        png_init_io(png, out.fp);
        png_set_IHDR(png, info, width, height, 8, PNG_COLOR_TYPE_RGB, PNG_INTERLACE_NONE,
                     PNG_COMPRESSION_TYPE_DEFAULT, PNG_FILTER_TYPE_DEFAULT);
        png_write_info(png, info);
        for (uint32_t y = 0; y < height; y++)
            png_write_row(png, rgb + (size_t)y * width * 3);
        png_write_end(png, info);
        ok = 1;
    }
    png_destroy_write_struct(png ? &png : NULL, info ? &info : NULL);
    if (!ok) {
        tsl_outfile_abort(&out);
        return -1;
    }
    if (tsl_outfile_commit(&out, &diag) != TESSEL_OK) {
        snprintf(err, errlen, "%s", diag.message);
        return -1;
    }
    return 0;
}
