/* Prints how much stack each call of the C ABI takes for an exported model, measured on
 * this machine: each call runs on a thread whose stack is painted with a pattern first,
 * and the bytes overwritten, less those of an empty thread, are the call's high-water
 * mark. Run it on the host with your firmware's model before sizing the task stacks
 * (the figures on an ARM build differ; the order of magnitude carries over).
 *
 *   strainwave export-c --config CONFIG --out model.h
 *   strainwave export-c --config CONFIG --precision f32 --name SW32_MODEL --out model32.h
 *   cc -std=c99 -O2 -I include -I . examples/c/stack_use.c LIB.a -lm -lpthread -ldl -o stack_use
 *   ./stack_use
 */
#define _POSIX_C_SOURCE 200809L
#include <pthread.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>

#include "strainwave.h"
#include "model.h"
#include "model32.h"

#define STACK_BYTES (1 << 20)
#define PAINT 0xA5
#define STEPS 3000

enum call { EMPTY, INIT, STEP, RESET, INIT32, STEP32, RESET32 };

static sw_state s64;
static sw32_state s32;
static unsigned char *stack;

/* Runs `call` (the step: STEPS samples of a turning joint, one with a torque glitch). */
static void *run(void *arg) {
    const enum call call = *(const enum call *)arg;
    sw_sample in = {0};
    sw32_sample in32 = {0};
    sw_output out;
    sw32_output out32;
    for (int k = 0; k < STEPS; k++) {
        in.time = k * 1e-3;
        in.motor_angle = 0.1 * k;
        in.output_angle = -0.001 * k;
        in.torque = k == STEPS / 2 ? 1e6 : 1.0;
        in32.time = (float)in.time;
        in32.motor_angle = (float)in.motor_angle;
        in32.output_angle = (float)in.output_angle;
        in32.torque = (float)in.torque;
        if (call == STEP) sw_step(&s64, &in, &out);
        if (call == STEP32) sw32_step(&s32, &in32, &out32);
    }
    if (call == INIT && sw_init(&s64, &SW_MODEL) != SW_OK) return "sw_init failed";
    if (call == INIT32 && sw32_init(&s32, &SW32_MODEL) != SW_OK) return "sw32_init failed";
    if (call == RESET) sw_reset(&s64);
    if (call == RESET32) sw32_reset(&s32);
    return NULL;
}

/* Bytes of the painted stack that `call` overwrote. */
static long high_water(enum call call) {
    memset(stack, PAINT, STACK_BYTES);
    pthread_attr_t attr;
    pthread_t thread;
    void *error = NULL;
    if (pthread_attr_init(&attr) || pthread_attr_setstack(&attr, stack, STACK_BYTES) ||
        pthread_create(&thread, &attr, run, &call) || pthread_join(thread, &error)) {
        fprintf(stderr, "cannot run a thread on the painted stack\n");
        exit(1);
    }
    if (error) {
        fprintf(stderr, "%s\n", (const char *)error);
        exit(1);
    }
    long untouched = 0;
    while (untouched < STACK_BYTES && stack[untouched] == PAINT) untouched++;
    return STACK_BYTES - untouched;
}

int main(void) {
    void *memory;
    if (posix_memalign(&memory, 4096, STACK_BYTES)) return 1;
    stack = memory;
    const long base = high_water(EMPTY);
    const char *names[] = {"", "sw_init", "sw_step", "sw_reset", "sw32_init", "sw32_step", "sw32_reset"};
    /* The order matters: a step and a reset need an initialised state. */
    for (enum call c = INIT; c <= RESET32; c++)
        printf("%-10s %6ld bytes of stack\n", names[c], high_water(c) - base);
    printf("sw_state %zu bytes, sw32_state %zu bytes (caller-owned)\n", sizeof(sw_state), sizeof(sw32_state));
    free(stack);
    return 0;
}
