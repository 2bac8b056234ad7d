#!/usr/bin/env bash
# Runs every libFuzzer target of tests/fuzz for SECONDS each (default 600), one at a
# time, built with AddressSanitizer and UndefinedBehaviorSanitizer in build-fuzz/
# (configured and built here when needed, with clang). Each target starts from its
# corpus, tests/fuzz/corpus/<target>/, and writes what it finds to a scratch copy;
# the repository's corpus changes only with --merge (inputs that add coverage).
#
# Usage: bench/fuzz.sh [SECONDS] [--merge] [--only TARGET]...
# Writes bench/results/fuzz-<UTC timestamp>.json: per target the seconds run,
# executions, exec/s, coverage (cov: edges, ft: features), peak RSS and the crashes;
# a crashing input is kept in bench/results/fuzz-<timestamp>-crashes/<target>/ with
# the fuzzer's log. Exit status 1 when any target crashed, leaked or hit a sanitizer.
set -euo pipefail
cd "$(dirname "$0")/.."
seconds=600
merge=0
only=()
while [[ $# -gt 0 ]]; do
  case "$1" in
    --merge) merge=1; shift ;;
    --only) only+=("$2"); shift 2 ;;
    [0-9]*) seconds=$1; shift ;;
    *) echo "usage: bench/fuzz.sh [SECONDS] [--merge] [--only TARGET]..." >&2; exit 2 ;;
  esac
done

build=${STRATA_FUZZ_BUILD_DIR:-build-fuzz}
if [[ ! -f "$build/build.ninja" ]]; then
  launcher=(); command -v ccache >/dev/null && launcher=(-DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
  CC=clang CXX=clang++ cmake -S . -B "$build" -G Ninja -DSTRATA_FUZZ=ON -DSTRATA_BUILD_TESTS=OFF \
    -DCMAKE_BUILD_TYPE=RelWithDebInfo "${launcher[@]}" >/dev/null
fi
nice -n 10 cmake --build "$build" -j "${STRATA_FUZZ_JOBS:-1}" --target strata_fuzz

targets=()
for dir in tests/fuzz/corpus/*/; do
  t=$(basename "$dir")
  if [[ ${#only[@]} -eq 0 || " ${only[*]} " == *" $t "* ]]; then targets+=("$t"); fi
done

stamp=$(date -u +%Y%m%dT%H%M%SZ)
commit=$(git rev-parse --short HEAD)$(git diff --quiet HEAD -- . ':!bench/results' || echo "+changes")
results=bench/results
mkdir -p "$results"
work=$(mktemp -d /tmp/strata-fuzz.XXXXXX)
trap 'rm -rf "$work"' EXIT
# A sanitizer report stops the run (no recovery) and is counted as a crash;
# leaks are checked after every input.
# A smaller quarantine (64 MB, default 256) halves the time of targets that allocate
# a lot in PROJ and SQLite; freed memory is still held long enough to catch a reuse.
export ASAN_OPTIONS=detect_leaks=1:symbolize=1:quarantine_size_mb=64
export LSAN_OPTIONS=suppressions=$PWD/tests/fuzz/lsan.supp:print_suppressions=0
export UBSAN_OPTIONS=print_stacktrace=1:halt_on_error=1

summaries=()
for t in "${targets[@]}"; do
  exe=$build/tests/fuzz/fuzz_$t
  corpus=tests/fuzz/corpus/$t
  mkdir -p "$work/$t/new" "$work/$t/crashes" "$work/$t/tmp"
  dict=(); [[ -f tests/fuzz/dict/$t.dict ]] && dict=(-dict="tests/fuzz/dict/$t.dict")
  echo "fuzz: $t for $seconds s" >&2
  start=$(date +%s)
  set +e
  # The fuzzer writes new inputs into the first folder only: the corpus stays as it is.
  TMPDIR=$work/$t/tmp nice -n 10 "$exe" "$work/$t/new" "$corpus" "${dict[@]}" \
    -max_total_time="$seconds" -timeout=25 -rss_limit_mb=2048 -print_final_stats=1 \
    -artifact_prefix="$work/$t/crashes/" >"$work/$t/log" 2>&1
  status=$?
  set -e
  elapsed=$(( $(date +%s) - start ))
  # Slow units (libFuzzer's slow-unit-*, over -report_slow_units seconds) are kept and
  # counted apart: a load-dependent time, not a crash. A unit over -timeout is a crash.
  crashes=$(find "$work/$t/crashes" -type f ! -name 'slow-unit-*' | wc -l)
  slow=$(find "$work/$t/crashes" -type f -name 'slow-unit-*' | wc -l)
  if [[ $status -ne 0 || $crashes -gt 0 || $slow -gt 0 ]]; then
    keep=$results/fuzz-$stamp-crashes/$t
    mkdir -p "$keep"
    cp "$work/$t/crashes"/* "$keep"/ 2>/dev/null || true
    cp "$work/$t/log" "$keep/fuzzer.log"
    if [[ $status -ne 0 || $crashes -gt 0 ]]; then
      echo "fuzz: $t FAILED (exit $status), see $keep" >&2
    else
      echo "fuzz: $t: $slow slow unit(s), kept in $keep" >&2
    fi
  fi
  if [[ $merge -eq 1 && $status -eq 0 ]]; then
    # Edges only (no hit counts): a few dozen inputs per target rather than hundreds.
    TMPDIR=$work/$t/tmp "$exe" -merge=1 -use_counters=0 "$corpus" "$work/$t/new" >"$work/$t/merge.log" 2>&1
  fi
  summaries+=("$(python3 - "$t" "$work/$t/log" "$elapsed" "$status" "$work/$t/crashes" "$corpus" <<'PY'
import json, os, re, sys
target, log, elapsed, status, crash_dir, corpus = sys.argv[1:]
text = open(log, errors="replace").read()
def stat(name):
    m = re.search(r"stat::%s:\s*(\d+)" % name, text)
    return int(m.group(1)) if m else None
last = [l for l in text.splitlines() if re.match(r"#\d+\s", l) and " cov: " in l]
cov = re.search(r"cov: (\d+)", last[-1]) if last else None
ft = re.search(r"ft: (\d+)", last[-1]) if last else None
reports = sorted(set(re.findall(r"(ERROR: (?:AddressSanitizer|LeakSanitizer|libFuzzer)[^\n]*|runtime error:[^\n]*|"
                                 r"terminate called[^\n]*)", text)))
files = sorted(f for f in os.listdir(crash_dir) if not f.startswith("slow-unit-"))
slow_files = sorted(f for f in os.listdir(crash_dir) if f.startswith("slow-unit-"))
corpus_files = [f for f in os.listdir(corpus)]
print(json.dumps({
    "target": target, "seconds": int(elapsed), "exit_status": int(status),
    "executions": stat("number_of_executed_units"), "exec_per_s": stat("average_exec_per_sec"),
    "cov": int(cov.group(1)) if cov else None, "ft": int(ft.group(1)) if ft else None,
    "peak_rss_mb": stat("peak_rss_mb"), "new_inputs": stat("new_units_added"),
    "corpus_files": len(corpus_files),
    "corpus_kb": sum(os.path.getsize(os.path.join(corpus, f)) for f in corpus_files) // 1024,
    "crashes": len(files), "crash_files": files, "reports": reports[:5],
    "slow_units": len(slow_files), "slowest_unit_s": stat("slowest_unit_time_sec"),
    "last_status": last[-1].strip() if last else None}))
PY
)")
done

out=$results/fuzz-$stamp.json
python3 - "$out" "$seconds" "$commit" "${summaries[@]}" <<'PY'
import json, sys
out, seconds, commit, *rows = sys.argv[1:]
rows = [json.loads(r) for r in rows]
doc = {"seconds_per_target": int(seconds), "commit": commit, "sanitizers": "address,undefined",
       "targets": rows, "crashed": [r["target"] for r in rows if r["crashes"] or r["exit_status"]]}
json.dump(doc, open(out, "w"), indent=2)
print(f"{'target':<14}{'s':>6}{'executions':>13}{'exec/s':>9}{'cov':>7}{'ft':>8}{'crashes':>9}{'slow':>6}")
for r in rows:
    print(f"{r['target']:<14}{r['seconds']:>6}{r['executions'] or 0:>13}{r['exec_per_s'] or 0:>9}"
          f"{r['cov'] or 0:>7}{r['ft'] or 0:>8}{r['crashes']:>9}{r['slow_units']:>6}")
print(f"written {out}")
sys.exit(1 if doc["crashed"] else 0)
PY
