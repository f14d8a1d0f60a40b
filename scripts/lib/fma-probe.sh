#!/usr/bin/env bash
# Prints how many 512-bit (and 128-bit) FMAs a core retires per nanosecond: sixteen independent
# chains of vfmadd231ps, more than two FMA units with a 4-cycle latency can overlap, so the rate
# is the units' throughput. Divided by the clock (clock-probe.sh) it gives FMAs per cycle: 2 on
# a core with two 512-bit FMA units, 1 on Xeons with one. Also prints the clock a busy core
# keeps under 512-bit FMAs (8 chains: one FMA latency, 4 cycles, per iteration, if the first
# line shows two units), which AVX-512 frequency licences may hold below clock-probe.sh's
# scalar figure. The roofline notes in docs/benchmarks.md use both.
set -euo pipefail
probe=${TMPDIR:-/tmp}/kestrel-fma-probe
if ! grep -qw avx512f /proc/cpuinfo; then
  echo "fma-probe: no AVX-512 on this machine"
  exit 0
fi
if [[ ! -x $probe ]]; then
  python3 - "$probe.c" <<'PY'
import sys
def chains(reg, n):
    return ''.join(f'"vfmadd231ps %%{reg}31, %%{reg}31, %%{reg}{i}\\n"' for i in range(n))
clobber = ','.join(f'"xmm{i}"' for i in range(16))
src = '''#include <stdio.h>
#include <time.h>
static double now(void) { struct timespec a; clock_gettime(CLOCK_MONOTONIC, &a); return a.tv_sec + 1e-9 * a.tv_nsec; }
#define N 100000000L
int main(void) {
    double t0, t;
    __asm__ volatile("vxorps %%zmm31, %%zmm31, %%zmm31" ::: "memory");
'''
for reg, n, what in [('zmm', 16, '512-bit FMAs per ns (16 chains)'), ('xmm', 16, '128-bit FMAs per ns (16 chains)'), ('zmm', 8, 'GHz under 512-bit FMAs (8 chains, 4-cycle latency)')]:
    rate = f'{n}.0 * N / t * 1e-9' if n == 16 else '4.0 * N / t * 1e-9'
    src += f'''    t0 = now();
    for (long i = 0; i < N; i++) __asm__ volatile({chains(reg, n)} ::: {clobber});
    t = now() - t0;
    printf("%.2f {what}\\n", {rate});
'''
src += '    return 0;\n}\n'
open(sys.argv[1], 'w').write(src)
PY
  cc -O1 -mavx512f -o "$probe" "$probe.c"
fi
"$probe"
