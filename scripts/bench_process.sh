#!/usr/bin/env bash
# Whole-process benchmarks of truepos against the cost of just reading the input (`wc -l` on the
# same files, in the same run), plus peak memory (`/usr/bin/time -v`, maximum resident set size).
# This is the table of issue 19; never run by CI.
#
#   scripts/bench_process.sh [REPS] [--big]
#
# TRUEPOS_BASELINE=path/to/other/truepos adds a "baseline" column: the same commands run by that
# binary, alternated with `wc -l` and truepos in the same loop, so a before/after comparison sees
# the same machine load (this 2-core machine is shared; separate runs are not comparable).
#
# REPS (default 5) runs of each command; the medians are reported with the ratio
# median(truepos) / median(wc -l). `--big` adds the 10M-point / 10M-line (and 5M-line) peak
# memory rows (about 1.5 GB of inputs under $TRUEPOS_BENCH_DIR, default /tmp/truepos-bench-proc).
# The inputs are generated once (awk and `truepos simulate latency`) and kept; delete the directory
# to regenerate. Build: `cargo build --release` (the script does it).
set -euo pipefail
cd "$(dirname "$0")/.."
REPS=${1:-5}
BIG=0
for a in "$@"; do [ "$a" = "--big" ] && BIG=1; done
WORK=${TRUEPOS_BENCH_DIR:-/tmp/truepos-bench-proc}
mkdir -p "$WORK"
[ -n "${TRUEPOS_BIN:-}" ] || cargo build --release -q -p truepos
BIN=${TRUEPOS_BIN:-$PWD/target/release/truepos}

# ---------------------------------------------------------------- inputs
# Noisy sphere (centre 10,20,30, radius 50), 6 decimals: ~33 bytes a line.
gen_sphere() { # N FILE
    [ -s "$2" ] && return
    awk -v n="$1" 'BEGIN { srand(7); print "x_mm,y_mm,z_mm";
        for (i = 0; i < n; i++) { u = 2*rand()-1; p = 6.283185307179586*rand(); s = sqrt(1-u*u);
            r = 50 + 0.002*(rand()-0.5);
            printf "%.6f,%.6f,%.6f\n", 10 + r*s*cos(p), 20 + r*s*sin(p), 30 + r*u } }' > "$2.tmp"
    mv "$2.tmp" "$2"
}
# Points inside the map's range with an id and a pass-through column, 6 decimals.
gen_points() { # N FILE
    [ -s "$2" ] && return
    awk -v n="$1" 'BEGIN { srand(11); print "id,x_mm,y_mm,z_mm,note";
        for (i = 0; i < n; i++) printf "P%d,%.6f,%.6f,%.6f,ok\n", i, 5+990*rand(), 5+790*rand(), 5+290*rand() }' > "$2.tmp"
    mv "$2.tmp" "$2"
}
# A 21-parameter map: 201 nodes per axis, smooth errors in µm / µrad.
gen_map() { # FILE
    [ -s "$1" ] && return
    awk 'BEGIN { print "axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad";
        split("x y z", ax, " "); len["x"] = 1000; len["y"] = 800; len["z"] = 400;
        for (k = 1; k <= 3; k++) { a = ax[k];
            for (j = 0; j <= 200; j++) { p = len[a]*j/200; s = p/len[a];
                printf "%s,%.3f,%.4f,%.4f,%.4f,%.4f,%.4f,%.4f\n", a, p, 3*s, 1.5*sin(3*s), -2*s*s, 4*s-2, 2*cos(2*s), 1.2*s } } }' > "$1"
}
# The wing-spar style program of scripts/bench_gcode.sh: N motion lines (~38 bytes a line).
gen_program() { # N FILE
    [ -s "$2" ] && return
    awk -v n="$1" 'BEGIN { print "%"; print "O1000 (WING SPAR)"; print "G21 G90 G17"; print "G0 X0 Y0 Z50";
        for (i = 0; i < n; i++) { x = (i % 1000) * 12.5; y = int(i / 1000) * 4.0;
            if (i % 50 == 0) printf "N%d G1 X%.3f Y%.3f F2000 (MSG,Measure SOMaC)\n", i+10, x, y;
            else printf "N%d G1 X%.3f Y%.3f\n", i+10, x, y }
        print "M30"; print "%" }' > "$2.tmp"
    mv "$2.tmp" "$2"
}
gen_targets() {
    [ -s "$WORK/nominal.csv" ] && return
    printf 'id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,10000,0,0\nT3,0,4000,0\nT4,10000,4000,30\n' > "$WORK/nominal.csv"
    # measured = 1.0001 · Rz(0.002 rad) · nominal + (1.5, -0.7, 0.2)
    awk 'BEGIN { c = cos(0.002); s = sin(0.002); k = 1.0001; print "id,x_mm,y_mm,z_mm";
        split("0 10000 0 10000", X, " "); split("0 0 4000 4000", Y, " "); split("0 0 0 30", Z, " ");
        for (i = 1; i <= 4; i++) printf "T%d,%.17g,%.17g,%.17g\n", i, k*(c*X[i]-s*Y[i])+1.5, k*(s*X[i]+c*Y[i])-0.7, k*Z[i]+0.2 }' > "$WORK/measured.csv"
}
# Latency streams: the simulator's sphere variant with enough repeats for ~1M rows per file.
gen_latency() {
    [ -s "$WORK/lat/machine.csv" ] && return
    "$BIN" simulate latency --out "$WORK/lat" --seed 3 --repeats "${LAT_REPEATS:-78}" >/dev/null
}

gen_sphere 1000000 "$WORK/sphere_1M.csv"
gen_points 1000000 "$WORK/points_1M.csv"
gen_map "$WORK/map.csv"
gen_program 1000000 "$WORK/prog_1M.nc"
gen_targets
gen_latency
if [ $BIG = 1 ]; then
    gen_points 10000000 "$WORK/points_10M.csv"
    gen_program 5000000 "$WORK/prog_5M.nc"
    gen_program 10000000 "$WORK/prog_10M.nc"
fi

# ---------------------------------------------------------------- timing
now() { date +%s%N; }
# time_cmd OUTVAR cmd...: one run, seconds (output discarded; a failure stops the script).
# FRESH=FILE (set for one `bench` call): FILE is removed, untimed, before each run, so that the
# command writes a new file instead of replacing the previous run's output (replacing a large
# file makes the file system free the old one's blocks inside the final rename: ≈ 25 ms for the
# 121 MB output of `comp correct` here, the same for any program, `cp` included).
run_once() {
    local s e
    [ -z "${FRESH:-}" ] || rm -f "$FRESH"
    s=$(now)
    "$@" >/dev/null 2>"$WORK/last_stderr" || { echo "FAILED: $*" >&2; cat "$WORK/last_stderr" >&2; exit 1; }
    e=$(now)
    echo $(( (e - s) / 1000 ))
}
median() { sort -n | awk '{ v[NR] = $1 } END { if (NR % 2) print v[(NR+1)/2]; else print (v[NR/2] + v[NR/2+1]) / 2 }'; }
# bench NAME INPUTS -- CMD...: REPS alternating runs of `wc -l INPUTS` and CMD; prints medians.
bench() {
    local name=$1; shift
    local inputs=()
    while [ "$1" != "--" ]; do inputs+=("$1"); shift; done
    shift
    cat "${inputs[@]}" > /dev/null   # page cache warm for both
    local tw=() tt=() tb=()
    for _ in $(seq "$REPS"); do
        tw+=("$(run_once wc -l "${inputs[@]}")")
        tt+=("$(run_once "$@")")
        [ -z "${TRUEPOS_BASELINE:-}" ] || tb+=("$(run_once "$TRUEPOS_BASELINE" "${@:2}")")
    done
    local mw mt mbase=0
    mw=$(printf '%s\n' "${tw[@]}" | median)
    mt=$(printf '%s\n' "${tt[@]}" | median)
    [ -z "${TRUEPOS_BASELINE:-}" ] || mbase=$(printf '%s\n' "${tb[@]}" | median)
    local mb
    mb=$(du -cm "${inputs[@]}" | tail -1 | cut -f1)
    awk -v n="$name" -v t="$mt" -v w="$mw" -v mb="$mb" -v b="$mbase" 'BEGIN {
        printf "| %-28s | %5d MB | %8.3f s | %8.4f s | %6.1f× |", n, mb, t/1e6, w/1e6, t/w;
        if (b > 0) printf " %8.3f s | %6.1f× |", b/1e6, b/w;
        printf "\n" }'
}
# peak NAME CMD...: maximum resident set size of one run.
peak() {
    local name=$1; shift
    local s e
    s=$(now)
    /usr/bin/time -v "$@" >/dev/null 2>"$WORK/time_v" || { echo "FAILED: $*" >&2; tail -30 "$WORK/time_v" >&2; exit 1; }
    e=$(now)
    awk -v n="$name" -v t="$(( (e - s) / 1000 ))" '/Maximum resident set size/ {
        printf "| %-28s | %8.3f s | %8.1f MB |\n", n, t/1e6, $NF/1024 }' "$WORK/time_v"
}

ORIENT=(orient --reference "$WORK/nominal.csv" --measured "$WORK/measured.csv" --scale)
CORRECT=(comp correct --map "$WORK/map.csv" --probe-offset-mm 0,0,-100)
echo "truepos $(git rev-parse --short HEAD) $(date -u +%FT%TZ); $(nproc) cores; load $(cut -d' ' -f1-3 /proc/loadavg); $REPS runs, medians"
echo
if [ -n "${TRUEPOS_BASELINE:-}" ]; then
    echo "baseline: $TRUEPOS_BASELINE"
    echo
    echo "| task | input | truepos | wc -l | ratio | baseline | baseline ratio |"
    echo "|---|---|---|---|---|---|---|"
else
    echo "| task | input | truepos | wc -l | ratio |"
    echo "|---|---|---|---|---|"
fi
bench "fit sphere, 1M points" "$WORK/sphere_1M.csv" -- "$BIN" fit sphere "$WORK/sphere_1M.csv" --json
bench "orient, 1M lines" "$WORK/prog_1M.nc" -- "$BIN" "${ORIENT[@]}" --program "$WORK/prog_1M.nc" --output "$WORK/out_1M.nc"
bench "comp correct, 1M points" "$WORK/points_1M.csv" -- "$BIN" "${CORRECT[@]}" --points "$WORK/points_1M.csv" --output "$WORK/corr_1M.csv"
FRESH="$WORK/corr_new.csv" bench "comp correct, 1M, new output" "$WORK/points_1M.csv" -- "$BIN" "${CORRECT[@]}" --points "$WORK/points_1M.csv" --output "$WORK/corr_new.csv"
bench "latency, $(($(wc -l < "$WORK/lat/machine.csv") / 1000))k + $(($(wc -l < "$WORK/lat/probe.csv") / 1000))k samples" "$WORK/lat/machine.csv" "$WORK/lat/probe.csv" -- \
    "$BIN" latency --machine "$WORK/lat/machine.csv" --probe "$WORK/lat/probe.csv" --json
echo
echo "| peak memory | time | max RSS |"
echo "|---|---|---|"
peak "orient, 1M lines" "$BIN" "${ORIENT[@]}" --program "$WORK/prog_1M.nc" --output "$WORK/out_1M.nc"
peak "comp correct, 1M points" "$BIN" "${CORRECT[@]}" --points "$WORK/points_1M.csv" --output "$WORK/corr_1M.csv"
if [ $BIG = 1 ]; then
    peak "orient, 5M lines" "$BIN" "${ORIENT[@]}" --program "$WORK/prog_5M.nc" --output "$WORK/out_5M.nc"
    peak "orient, 10M lines" "$BIN" "${ORIENT[@]}" --program "$WORK/prog_10M.nc" --output "$WORK/out_10M.nc"
    peak "comp correct, 10M points" "$BIN" "${CORRECT[@]}" --points "$WORK/points_10M.csv" --output "$WORK/corr_10M.csv"
    rm -f "$WORK/out_5M.nc" "$WORK/out_10M.nc" "$WORK/corr_10M.csv"
fi
