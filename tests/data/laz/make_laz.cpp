// Test-file generator for tessel's LAZ reader: writes a LAZ file (the LASzip
// reference encoder) and its uncompressed LAS twin from simple.las's first n
// points, with the other fields of point format F filled in a fixed pattern.
// Usage: make_laz simple.las FORMAT N EXTRA_BYTES CHUNK_SIZE CHANNELS OUT_PREFIX
// (CHANNELS 0: the input's own fields, no pattern, one channel)
// Environment: LAZ_VERSION (item version), LAZ_COMPRESSOR (1 or 2 for 0-5).
#include "laszip_api.h"
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
static const int min_len[11] = {20, 28, 26, 34, 57, 63, 30, 36, 38, 59, 67};
static unsigned rng = 12345;
static unsigned rnd(void) { rng = rng * 1103515245u + 12345u; return (rng >> 16) & 0x7FFF; }
static int write_file(laszip_header *src, laszip_point *pts, int n, int fmt, int extra, int chunk,
                      int channels, const char *path, int compress) {
  laszip_POINTER w; laszip_create(&w);
  laszip_header h; memset(&h, 0, sizeof h);
  h.version_major = 1; h.version_minor = fmt >= 6 ? 4 : fmt >= 4 ? 3 : 2;
  h.header_size = fmt >= 6 ? 375 : fmt >= 4 ? 235 : 227;
  h.offset_to_point_data = h.header_size;
  h.point_data_format = fmt; h.point_data_record_length = min_len[fmt] + extra;
  if (fmt <= 5) h.number_of_point_records = n;
  h.extended_number_of_point_records = n;
  strcpy(h.generating_software, "tessel test (LASzip)");
  h.x_scale_factor = src->x_scale_factor; h.y_scale_factor = src->y_scale_factor; h.z_scale_factor = src->z_scale_factor;
  h.x_offset = src->x_offset; h.y_offset = src->y_offset; h.z_offset = src->z_offset;
  double mn[3], mx[3];
  for (int i = 0; i < n; i++) {
    double v[3] = {pts[i].X * h.x_scale_factor + h.x_offset, pts[i].Y * h.y_scale_factor + h.y_offset, pts[i].Z * h.z_scale_factor + h.z_offset};
    for (int k = 0; k < 3; k++) { if (!i || v[k] < mn[k]) mn[k] = v[k]; if (!i || v[k] > mx[k]) mx[k] = v[k]; }
  }
  h.min_x = mn[0]; h.min_y = mn[1]; h.min_z = mn[2]; h.max_x = mx[0]; h.max_y = mx[1]; h.max_z = mx[2];
  if (laszip_set_header(w, &h)) { char *e; laszip_get_error(w, &e); fprintf(stderr, "%s\n", e); return 1; }
  if (chunk) laszip_set_chunk_size(w, chunk);
  if (fmt >= 6) laszip_request_native_extension(w, 1);
  if (laszip_open_writer(w, path, compress)) { char *e; laszip_get_error(w, &e); fprintf(stderr, "%s\n", e); return 1; }
  laszip_point *p; laszip_get_point_pointer(w, &p);
  for (int i = 0; i < n; i++) {
    unsigned char *eb = p->extra_bytes; int neb = p->num_extra_bytes;
    *p = pts[i];
    p->extra_bytes = eb; p->num_extra_bytes = neb;
    for (int b = 0; b < neb && eb; b++) eb[b] = b == 1 ? 7 : (unsigned char)(b == 0 ? i : (i * 13 + b) / 5);
    if (laszip_write_point(w)) { char *e; laszip_get_error(w, &e); fprintf(stderr, "%s\n", e); return 1; }
  }
  laszip_close_writer(w); laszip_destroy(w);
  return 0;
}
int main(int argc, char **argv) {
  int fmt = atoi(argv[2]), n = atoi(argv[3]), extra = atoi(argv[4]), chunk = atoi(argv[5]), channels = atoi(argv[6]);
  laszip_POINTER r; laszip_BOOL c; laszip_header *h; laszip_point *p;
  laszip_create(&r); if (laszip_open_reader(r, argv[1], &c)) return 1;
  laszip_get_header_pointer(r, &h); laszip_get_point_pointer(r, &p);
  laszip_point *pts = (laszip_point *)calloc(n, sizeof *pts);
  double t = 0;
  for (int i = 0; i < n; i++) {
    laszip_read_point(r);
    laszip_point q = *p; q.extra_bytes = 0; q.num_extra_bytes = 0;
    if (fmt >= 6 && channels == 0) {
      /* plain: the format-3 fields as they are */
      q.extended_number_of_returns = p->number_of_returns; q.extended_return_number = p->return_number;
      q.extended_classification = p->classification;
      q.extended_classification_flags = p->synthetic_flag | (p->keypoint_flag << 1) | (p->withheld_flag << 2);
      q.extended_scan_angle = (short)(p->scan_angle_rank / 0.006 + (p->scan_angle_rank >= 0 ? 0.5 : -0.5));
      q.extended_scanner_channel = 0;
      q.extended_point_type = 1;
    } else if (fmt >= 6) {
      /* returns up to 15, classes above 31, channels that come back */
      int nr = 1 + (i / 7) % 15, rn = 1 + i % nr;
      q.extended_number_of_returns = nr; q.extended_return_number = rn;
      q.number_of_returns = nr > 7 ? 7 : nr; q.return_number = rn > 7 ? 7 : rn;
      q.extended_classification = (i % 50 == 0) ? 40 + i % 7 : p->classification;
      q.classification = q.extended_classification < 32 ? q.extended_classification : 0;
      q.extended_classification_flags = (i / 90) % 16;
      q.synthetic_flag = q.extended_classification_flags & 1;
      q.keypoint_flag = (q.extended_classification_flags >> 1) & 1;
      q.withheld_flag = (q.extended_classification_flags >> 2) & 1;
      q.extended_scan_angle = (short)(p->scan_angle_rank * 166 + (i % 5 == 0 ? i : 0));
      q.extended_scanner_channel = channels > 1 ? ((i / 11) * 7 + (i / 53)) % channels : 0;
      q.extended_point_type = 1;
    }
    if ((fmt == 1 || fmt == 3 || fmt >= 4) && channels > 0) {
      if (i % 3 == 0) t += 0.00025 * (1 + rnd() % 4);
      if (i == n * 3 / 4) t += 1e6;  /* a jump the 32-bit differences cannot code */
      q.gps_time = p->gps_time + t;
    }
    if (channels > 0) q.rgb[3] = (unsigned short)(i * 37 % 2000 + (i % 9 == 0 ? 40000 : 0));
    if (fmt == 4 || fmt == 5 || fmt >= 9) {
      unsigned char *w = q.wave_packet;
      w[0] = 1 + i % 3;
      unsigned long long off = 1000 + (unsigned long long)i * 256 + (i % 17 == 0 ? 99999 : 0);
      unsigned size = i % 23 == 0 ? 512 : 256;
      float rp = 10.5f + (float)(i % 5), xyz[3] = {0.001f * i, -0.002f, 0.5f + 0.01f * (i % 4)};
      memcpy(w + 1, &off, 8); memcpy(w + 9, &size, 4); memcpy(w + 13, &rp, 4); memcpy(w + 17, xyz, 12);
    }
    pts[i] = q;
  }
  char path[512];
  snprintf(path, sizeof path, "%s.laz", argv[7]);
  if (write_file(h, pts, n, fmt, extra, chunk, channels, path, 1)) return 1;
  snprintf(path, sizeof path, "%s.las", argv[7]);
  if (write_file(h, pts, n, fmt, extra, chunk, channels, path, 0)) return 1;
  return 0;
}
