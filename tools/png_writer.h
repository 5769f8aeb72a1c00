/* PNG output for `tessel render`: RGB8 images through libpng. (Not named
 * png.h: with tools/ on the include path it would shadow <png.h>.) The library
 * itself does not depend on libpng; only the CLI links it. */
#ifndef TESSEL_CLI_PNG_WRITER_H
#define TESSEL_CLI_PNG_WRITER_H

#include <stddef.h>
#include <stdint.h>

/* Writes width x height RGB8 pixels (rows top to bottom, 3 bytes each) to
 * path as an 8-bit RGB PNG. The file is written under a temporary name in
 * the destination's folder and renamed over path only when complete, so a
 * failure never leaves a partial file. Returns 0 on success; otherwise -1
 * with a message (naming the cause) in err. */
int png_write_rgb(const char *path, const uint8_t *rgb, uint32_t width, uint32_t height,
                  char *err, size_t errlen);

#endif /* TESSEL_CLI_PNG_WRITER_H */
