#!/usr/bin/env bash
# Prints the clock a busy core runs at now (a dependent-add loop, one add per cycle), in GHz.
# The machine is a VM on shared hosts: the same binary has been seen at 1.6 and 2.9 GHz in one
# hour, so benchmark tables quote this beside their figures.
set -euo pipefail
probe=${TMPDIR:-/tmp}/kestrel-clock-probe
if [[ ! -x $probe ]]; then
  cat >"$probe.c" <<'C'
#include <stdio.h>
#include <time.h>
int main(void) {
    struct timespec a, b;
    clock_gettime(CLOCK_MONOTONIC, &a);
    unsigned long x = 0;
    for (long i = 0; i < 1000000000L; i++) __asm__ volatile("add $1, %0" : "+r"(x));
    clock_gettime(CLOCK_MONOTONIC, &b);
    printf("%.2f\n", 1.0 / ((b.tv_sec - a.tv_sec) + 1e-9 * (b.tv_nsec - a.tv_nsec)));
    return 0;
}
C
  cc -O1 -o "$probe" "$probe.c"
fi
"$probe"
