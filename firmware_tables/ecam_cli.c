/*
 * ecam_cli.c - test driver for the ecam C runtime.
 *
 *   ecam_cli BLOBFILE              init, then for every stdin line "master_counts" (decimal int64)
 *                                  print "position slope"; blank lines are skipped.
 *   ecam_cli --check BLOBFILE...   init only; print "ok" or "error <code> <name>" per file, in
 *                                  argument order.
 *
 * Exit status: 0 success, 1 a blob was rejected, 2 usage, I/O or input syntax error.
 * Unlike the runtime, this host tool may allocate (it holds the whole blob in memory).
 */
#include <errno.h>
#include <inttypes.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "ecam_host_io.h"
#include "ecam_table.h"

#define ECAM_CLI_IO_BUFFER (1u << 16)
#define ECAM_CLI_LINE_MAX 256

/* Loads and validates one blob; prints the error line itself so both modes report alike. */
static int ecam_cli_load(const char *path, ecam_table *table, uint8_t **blob)
{
    size_t len = 0;
    int status;

    *blob = ecam_host_read_file(path, &len);
    if (*blob == NULL) {
        fprintf(stderr, "ecam_cli: cannot read %s\n", path);
        return 2;
    }
    status = ecam_table_init(table, *blob, len);
    if (status != ECAM_OK) {
        printf("error %d %s\n", status, ecam_status_name(status));
        return 1;
    }
    return 0;
}

/* --check mode: validates each file, so a whole directory of blobs costs one process. */
static int ecam_cli_check(int count, char **paths)
{
    int worst = 0;
    int i;

    for (i = 0; i < count; i++) {
        ecam_table table;
        uint8_t *blob = NULL;
        int rc = ecam_cli_load(paths[i], &table, &blob);

        if (rc == 0) {
            printf("ok\n");
        }
        free(blob);
        if (rc > worst) {
            worst = rc;
        }
    }
    return worst;
}

/* True for a line holding only whitespace, which is skipped rather than treated as an error. */
static int ecam_cli_blank(const char *s)
{
    while (*s == ' ' || *s == '\t' || *s == '\r' || *s == '\n') {
        s++;
    }
    return *s == '\0';
}

/* Strict decimal int64 parse: the whole line must be one in-range number. */
static int ecam_cli_parse(const char *line, int64_t *value)
{
    char *end = NULL;
    long long v;

    errno = 0;
    v = strtoll(line, &end, 10);
    if (end == line || errno != 0 || !ecam_cli_blank(end)) {
        return 0;
    }
    *value = (int64_t)v;
    return 1;
}

/* Lookup mode: stdin master counts to stdout "position slope", fully buffered for speed. */
static int ecam_cli_lookup(const char *path)
{
    static char out_buffer[ECAM_CLI_IO_BUFFER];
    static char in_buffer[ECAM_CLI_IO_BUFFER];
    char line[ECAM_CLI_LINE_MAX];
    ecam_table table;
    uint8_t *blob = NULL;
    unsigned long line_no = 0;
    int rc = ecam_cli_load(path, &table, &blob);

    if (rc != 0) {
        free(blob);
        return rc;
    }
    setvbuf(stdout, out_buffer, _IOFBF, sizeof out_buffer);
    setvbuf(stdin, in_buffer, _IOFBF, sizeof in_buffer);
    while (fgets(line, sizeof line, stdin) != NULL) {
        int64_t master;
        int32_t position;
        int32_t slope;

        line_no++;
        if (ecam_cli_blank(line)) {
            continue;
        }
        if (strchr(line, '\n') == NULL && !feof(stdin)) {
            fprintf(stderr, "ecam_cli: line %lu too long\n", line_no);
            rc = 2;
            break;
        }
        if (!ecam_cli_parse(line, &master)) {
            fprintf(stderr, "ecam_cli: line %lu is not a decimal int64\n", line_no);
            rc = 2;
            break;
        }
        ecam_table_lookup(&table, master, &position, &slope);
        printf("%" PRId32 " %" PRId32 "\n", position, slope);
    }
    if (rc == 0 && ferror(stdin)) {
        fprintf(stderr, "ecam_cli: error reading stdin\n");
        rc = 2;
    }
    if (fflush(stdout) != 0 && rc == 0) {
        rc = 2;
    }
    free(blob);
    return rc;
}

/* Entry point: dispatch on the two documented command lines. */
int main(int argc, char **argv)
{
    if (argc >= 3 && strcmp(argv[1], "--check") == 0) {
        return ecam_cli_check(argc - 2, argv + 2);
    }
    if (argc == 2 && strncmp(argv[1], "--", 2) != 0) {
        return ecam_cli_lookup(argv[1]);
    }
    fprintf(stderr, "usage: ecam_cli BLOBFILE < master_counts\n"
                    "       ecam_cli --check BLOBFILE...\n");
    return 2;
}
