/* Runs every row of a CSV recording through the strainwave canceller with a model that
 * `strainwave export-c` wrote, and writes the rows with the canceller's columns added
 * (torque, ripple, misalignment, innovation, nis, filter_flags), as `strainwave filter`
 * does for the same config.
 *
 *   strainwave export-c --config examples/joint-taghirad.toml --out joint_model.h
 *   cc -std=c99 -O2 -I include -I . examples/c/filter_csv.c target/release/libstrainwave_ffi.a -lm -o filter_csv
 *   ./filter_csv taghirad.csv filtered.csv
 *
 * Plain comma-separated values with a header row, no quoted fields. Firmware does the
 * same per sample without the file handling: sw_init once, sw_step every sample. */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "strainwave.h"

#ifndef SW_MODEL_HEADER
#define SW_MODEL_HEADER "joint_model.h"
#endif
#include SW_MODEL_HEADER

#define MAX_LINE 65536
#define MAX_COLUMNS 512

/* Splits `line` at commas in place; returns the number of fields, -1 if too many. */
static int split(char *line, char **fields) {
    int n = 0;
    char *p = line;
    for (;;) {
        if (n == MAX_COLUMNS) return -1;
        fields[n++] = p;
        char *comma = strchr(p, ',');
        if (!comma) break;
        *comma = '\0';
        p = comma + 1;
    }
    return n;
}

/* Removes a trailing newline (and carriage return); returns 0 if the line was cut short. */
static int chomp(char *line, FILE *f) {
    size_t len = strlen(line);
    if (len == 0 || line[len - 1] != '\n') return feof(f) || len < MAX_LINE - 1;
    line[--len] = '\0';
    if (len > 0 && line[len - 1] == '\r') line[--len] = '\0';
    return 1;
}

/* Index of the channel's column, -1 when the config has no such channel, -2 if missing. */
static int column_of(const sw_channel *ch, char **names, int count) {
    if (!ch->column) return -1;
    for (int i = 0; i < count; i++)
        if (strcmp(names[i], ch->column) == 0) return i;
    fprintf(stderr, "no column `%s` in the recording\n", ch->column);
    return -2;
}

static double value(const sw_channel *ch, int index, char **fields, int count) {
    if (index < 0 || index >= count) return NAN;
    char *end;
    double v = strtod(fields[index], &end);
    if (end == fields[index]) return NAN;
    return v * ch->scale + ch->offset;
}

int main(int argc, char **argv) {
    if (argc != 3) {
        fprintf(stderr, "usage: %s IN.csv OUT.csv\n", argv[0]);
        return 2;
    }
    FILE *in = fopen(argv[1], "r");
    if (!in) { perror(argv[1]); return 1; }
    FILE *out = fopen(argv[2], "w");
    if (!out) { perror(argv[2]); return 1; }

    static sw_state state; /* 12 KB: static, as firmware would keep it */
    int rc = sw_init(&state, &SW_MODEL);
    if (rc != SW_OK) {
        fprintf(stderr, "sw_init: %s\n", sw_error_text(rc));
        return 1;
    }

    static char line[MAX_LINE], copy[MAX_LINE];
    static char *names[MAX_COLUMNS], *fields[MAX_COLUMNS];
    if (!fgets(line, sizeof line, in) || !chomp(line, in)) { fprintf(stderr, "%s: no header row\n", argv[1]); return 1; }
    fprintf(out, "%s,torque,ripple,misalignment,innovation,nis,filter_flags\n", line);
    int count = split(line, names);
    if (count < 0) { fprintf(stderr, "%s: more than %d columns\n", argv[1], MAX_COLUMNS); return 1; }

    const sw_channels *c = &SW_MODEL_CHANNELS;
    const sw_channel *channels[6] = {&c->time, &c->torque, &c->motor_angle, &c->output_angle,
                                     &c->motor_velocity, &c->expected_torque};
    int index[6];
    for (int k = 0; k < 6; k++)
        if ((index[k] = column_of(channels[k], names, count)) == -2) return 1;

    long row = 0;
    while (fgets(line, sizeof line, in)) {
        row++;
        if (!chomp(line, in)) { fprintf(stderr, "%s: data row %ld longer than %d bytes\n", argv[1], row, MAX_LINE); return 1; }
        if (line[0] == '\0') continue;
        memcpy(copy, line, strlen(line) + 1);
        int n = split(copy, fields);
        if (n < 0) { fprintf(stderr, "%s: data row %ld: too many fields\n", argv[1], row); return 1; }
        double v[6];
        for (int k = 0; k < 6; k++) v[k] = value(channels[k], index[k], fields, n);
        sw_sample sample = {v[0], v[1], v[2], v[3], v[4], v[5]};
        sw_output o;
        rc = sw_step(&state, &sample, &o);
        if (rc != SW_OK) {
            fprintf(stderr, "%s: data row %ld: %s\n", argv[1], row, sw_error_text(rc));
            return 1;
        }
        /* `filter_flags` as `strainwave filter` writes them: the core's flags (bits 0-7), the
         * guard's (from bit 8) and the orders it did not apply (from bit 16). */
        unsigned flags = (o.flags & 0xffu) | (o.guard_flags << 8) | (o.withheld_orders << 16);
        fprintf(out, "%s,%.17g,%.17g,%.17g,%.17g,%.17g,%u\n", line, o.torque, o.ripple, o.misalignment,
                o.innovation, o.nis, flags);
    }
    if (fclose(out) != 0) { perror(argv[2]); return 1; }
    fclose(in);
    return 0;
}
