/*
 * ecam_host_io.c - file input for the runtime's drivers; see ecam_host_io.h. Allocates (it is
 * no part of the runtime).
 */
#include "ecam_host_io.h"

#include <stdio.h>
#include <stdlib.h>

/* Whole file, read to its end into a doubling buffer: the runtime validates a blob as one
 * contiguous buffer. */
uint8_t *ecam_host_read_file(const char *path, size_t *len)
{
    FILE *f = fopen(path, "rb");
    uint8_t *data = NULL;
    size_t cap = 0;
    size_t used = 0;

    if (f == NULL) {
        return NULL;
    }
    for (;;) {
        if (used == cap) {
            size_t new_cap = cap == 0 ? 4096u : cap * 2u;
            uint8_t *grown = new_cap < cap ? NULL : realloc(data, new_cap);
            if (grown == NULL) {
                break;
            }
            data = grown;
            cap = new_cap;
        }
        used += fread(data + used, 1, cap - used, f);
        if (used < cap) { /* fread stops short only at end of file or on an error */
            if (ferror(f)) {
                break;
            }
            fclose(f);
            *len = used;
            return data;
        }
    }
    free(data);
    fclose(f);
    return NULL;
}
