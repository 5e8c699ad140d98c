/* The C side of benchmarks/vm_bench.py: how many control steps per CPU second the C BittyBuzz
 * library runs on one compiled script, driven the way vm_bench.py drives our VM.
 *
 * Design: the library is the user's checkout (BBZIDE_BITTYBUZZ_SRC), compiled by vm_bench.py
 * with -O2 together with this file and a config.h written for the profile; nothing of it is
 * in this repository. The harness does only what the benchmark needs: construct, set the
 * bytecode, run the top level, add the neighbours, then call `step` (self nil pushed first,
 * result popped) until the CPU time is spent. Host functions the script calls (led, motion,
 * ...) are registered as closures that return at once. The library keeps no instruction
 * counter, so the harness counts steps; vm_bench.py multiplies by the instructions per step
 * that our VM counts on the same .bbo (both VMs run the same instructions: the conformance
 * corpus checks it).
 *
 *   bbz_c_rate FILE.bbo STEP_SID NEIGHBOURS SECONDS [HOST_SID ...]
 * prints "steps N cpu_seconds T"; exit status 1 and a one-line reason on an error.
 */
#include <stdio.h>
#include <stdlib.h>
#include <time.h>

#include "bittybuzz/bbzvm.h"

static bbzvm_t vm_record;
static uint8_t* code;
static long code_size;

static const uint8_t* fetch(bbzpc_t offset, uint8_t size) {
    (void)size;
    return code + offset;
}

static void host_noop(void) { bbzvm_ret0(); }

static double cpu_seconds(void) { return (double)clock() / CLOCKS_PER_SEC; }

static int failed(const char* where) {
    if (vm->state != BBZVM_STATE_ERROR) return 0;
    printf("error %d in %s at pc %d\n", (int)vm->error, where, (int)vm->pc);
    return 1;
}

int main(int argc, char** argv) {
    if (argc < 5) {
        fprintf(stderr, "usage: %s FILE.bbo STEP_SID NEIGHBOURS SECONDS [HOST_SID ...]\n", argv[0]);
        return 2;
    }
    FILE* f = fopen(argv[1], "rb");
    if (!f) { printf("cannot read %s\n", argv[1]); return 1; }
    fseek(f, 0, SEEK_END);
    code_size = ftell(f);
    fseek(f, 0, SEEK_SET);
    code = malloc((size_t)code_size + 4);  /* + 4: a fetch of the last operand stays inside */
    if (fread(code, 1, (size_t)code_size, f) != (size_t)code_size) { printf("short read\n"); return 1; }
    fclose(f);
    uint16_t step_sid = (uint16_t)atoi(argv[2]);
    int neighbours = atoi(argv[3]);
    double seconds = atof(argv[4]);

    vm = &vm_record;
    bbzvm_construct(0);
    bbzvm_set_bcode(fetch, (uint16_t)code_size);
    for (int i = 5; i < argc; ++i) bbzvm_function_register((int16_t)atoi(argv[i]), host_noop);
    while (vm->state == BBZVM_STATE_READY) bbzvm_step();
    if (failed("top level")) return 1;
    vm->state = BBZVM_STATE_READY;
    /* neighbour r at 10 r cm, azimuth 3 r, elevation 0: vm_bench.add_neighbors */
    for (int r = 1; r <= neighbours; ++r) {
        bbzneighbors_elem_t e;
        e.robot = (bbzrobot_id_t)r;
#ifdef BBZ_NEIGHBORS_USE_FLOATS
        e.distance = bbzfloat_fromfloat(10.0f * r);
        e.azimuth = bbzfloat_fromfloat(3.0f * r);
        e.elevation = bbzfloat_fromfloat(0.0f);
#else
        e.distance = (uint8_t)(10 * r > 255 ? 255 : 10 * r);
        e.azimuth = (uint8_t)(3 * r);
        e.elevation = 0;
#endif
        bbzneighbors_add(&e);
        if (failed("neighbors_add")) return 1;
    }
    long steps = 0;
    double start = cpu_seconds();
    double spent = 0.0;
    while (spent < seconds) {
        bbzvm_pushnil();
        bbzvm_function_call(step_sid, 0);
        if (failed("step")) return 1;
        bbzvm_pop();
        ++steps;
        if ((steps & 63) == 0) spent = cpu_seconds() - start;
    }
    spent = cpu_seconds() - start;
    printf("steps %ld cpu_seconds %.6f\n", steps, spent);
    return 0;
}
