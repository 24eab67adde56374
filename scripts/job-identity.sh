#!/usr/bin/env bash
# Byte identity of print jobs across builds: slices the benchmark classes (spring, lattice, curved lattice,
# made exactly by rodfab_generate_examples) with each ditherer (white, blue, error diffusion) on 1 and 2
# threads, seed 7, into OUTDIR/<class>-<ditherer>-<threads>/job.zip; with --against REFDIR, compares each
# job with REFDIR's (cmp) and exits 1 if any differs. A change that must keep the jobs' bytes is checked by
# running this with the old build into REFDIR, then with the new one --against it (about 3 minutes a run).
# With --contents (for a change that may alter the container's bytes but not what the job holds) each job
# is compared by scripts/job_contents.py instead of cmp: the same entry names, every layer image and file
# the same bytes once decompressed, the previews the same decoded pixels, the report and manifest the same
# apart from the previews' encoding (its docstring says exactly what is compared).
#   scripts/job-identity.sh [--rodfab BIN] OUTDIR [--against REFDIR [--contents]]
set -euo pipefail
cd "$(dirname "$0")/.."
rodfab=build/slicer/rodfab
generator=build/examples/rodfab_generate_examples
if [ "${1:-}" = "--rodfab" ]; then rodfab=$2; shift 2; fi
[ $# -ge 1 ] || { echo "usage: scripts/job-identity.sh [--rodfab BIN] OUTDIR [--against REFDIR [--contents]]" >&2; exit 2; }
out=$1; against=""
if [ "${2:-}" = "--against" ]; then against=${3:?--against needs a folder}; fi
contents=""
if [ "${4:-}" = "--contents" ]; then contents=1; fi
[ -x "$rodfab" ] && [ -x "$generator" ] || { echo "build first (scripts/build.sh): $rodfab or $generator missing" >&2; exit 2; }
mkdir -p "$out/designs"
for design in spring lattice curved-lattice; do
  [ -f "$out/designs/$design.json" ] || "$generator" --benchmark "$design" "$out/designs/$design.json" > /dev/null
  for dither in white blue error-diffusion; do
    for threads in 1 2; do
      case=$design-$dither-$threads
      mkdir -p "$out/$case"
      "$rodfab" slice "$out/designs/$design.json" --dither "$dither" --threads "$threads" --seed 7 \
        --output "$out/$case/job.zip" --force --quiet > /dev/null
    done
  done
done
echo "wrote 18 jobs in $out"
[ -n "$against" ] || exit 0
differ=0
for job in "$out"/*/job.zip; do
  case=$(basename "$(dirname "$job")")
  if [ -n "$contents" ]; then
    if report=$(python3 scripts/job_contents.py "$job" "$against/$case/job.zip"); then echo "same contents  $case: ${report#same contents: }"
    else echo "DIFFERS $case"; echo "$report" | head -5 | sed 's/^/    /'; differ=1; fi
  elif cmp -s "$job" "$against/$case/job.zip"; then echo "same    $case"; else echo "DIFFERS $case"; differ=1; fi
done
exit $differ
