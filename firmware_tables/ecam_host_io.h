/*
 * ecam_host_io.h - file input for the runtime's drivers (ecam_cli, ecam_bench, ecam_target).
 *
 * Not part of the runtime: the runtime takes a blob the caller holds and never allocates, while
 * these tools read whole files (stdio on a host, semihosting on the Cortex-M4 target) into heap
 * buffers. Firmware copies ecam_table.h/.c only; this file stays with the tools.
 */
#ifndef ECAM_HOST_IO_H
#define ECAM_HOST_IO_H

#include <stddef.h>
#include <stdint.h>

/* The whole file at `path` in a fresh malloc'd buffer (free it), its size in *len; NULL on any
 * error (open, read or memory), *len then untouched. An empty file gives a non-NULL buffer. */
uint8_t *ecam_host_read_file(const char *path, size_t *len);

#endif /* ECAM_HOST_IO_H */
