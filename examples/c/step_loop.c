/* Steps the f64 and f32 canceller N times on a synthetic joint (30 rad/s motor, wrapped
 * angles, a steady load with ripple): a fixed workload for instruction counts, e.g.
 *
 *   strainwave export-c --config CONFIG --out model.h
 *   strainwave export-c --config CONFIG --precision f32 --name SW32_MODEL --out model32.h
 *   cc -std=c99 -O2 -I include -I . examples/c/step_loop.c LIB.a -lm -lpthread -ldl -o step_loop
 *   valgrind --tool=callgrind ./step_loop 10000     (inclusive Ir of sw_step / sw32_step)
 */
#include <math.h>
#include <stdio.h>
#include <stdlib.h>

#include "strainwave.h"
#include "model.h"
#include "model32.h"

int main(int argc, char **argv) {
    const long n = argc > 1 ? strtol(argv[1], NULL, 10) : 10000;
    static sw32_state s32;
    static sw_state s64;
    int rc = sw32_init(&s32, &SW32_MODEL);
    if (rc == SW_OK) rc = sw_init(&s64, &SW_MODEL);
    if (rc != SW_OK) {
        fprintf(stderr, "init: %s\n", sw_error_text(rc));
        return 1;
    }
    const double tau = 6.283185307179586, gain = SW_MODEL.calibration.alpha[0];
    double sum32 = 0.0, sum64 = 0.0;
    for (long k = 0; k < n; k++) {
        const double t = k * 1e-3, motor = fmod(30.0 * t, tau), output = fmod(0.3 * t, tau);
        const double raw = (10.0 + 0.3 * sin(2.0 * motor) + 0.2 * cos(output)) / gain;
        const sw32_sample a = {(float)fmod(t, 1000.0), (float)raw, (float)motor, (float)output, 30.0f, NAN};
        const sw_sample b = {t, raw, motor, output, 30.0, NAN};
        sw32_output o32;
        sw_output o64;
        if (sw32_step(&s32, &a, &o32) != SW_OK || sw_step(&s64, &b, &o64) != SW_OK) return 1;
        sum32 += o32.torque;
        sum64 += o64.torque;
    }
    printf("mean clean torque over %ld steps: f32 %.4f N·m, f64 %.4f N·m\n", n, sum32 / n, sum64 / n);
    return 0;
}
