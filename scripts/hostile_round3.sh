#!/usr/bin/env bash
# Fresh hostile audit of issue 31 (round 3, audit 31): ten classes, new variations of the
# classes of the 410-case audit. One TSV line per case: class, case, exit code, first line of
# stderr (the first line beginning with "error" when there is one, else the first line; 120
# chars), seconds, peak RSS (kB). Output checks ("... left byte-identical") are cases of their own.
# Usage: scripts/hostile_round3.sh path/to/truepos > cases.tsv
# Each case: timeout 20 s (exit 124), address space 2 GB (prlimit; an allocation beyond it aborts,
# exit 134), pinned to core 1 (set PIN="" to run unpinned). Inputs are generated in a temp dir
# (KEEP=1 keeps it); Parquet cases need pyarrow (python3), the rest python3 only.
set -u
T=$(realpath "${1:?usage: hostile_round3.sh TRUEPOS_BINARY}")
REPO=$(cd "$(dirname "$0")/.." && pwd)
PIN=${PIN-taskset -c 1 nice -n 5}
TO=${TIMEOUT:-20}
D=$(mktemp -d "${TMPDIR:-/tmp}/hostile31.XXXXXX")
BG=()
cleanup() { for p in "${BG[@]}"; do kill "$p" 2>/dev/null; done; [ -n "${KEEP:-}" ] || rm -rf "$D"; }
trap cleanup EXIT
cd "$D"
for e in csv ds toml nc dms qif parquet e57 json; do truncate -s 3G sparse.$e; done  # 3 GB sparse inputs
ulimit -f 1048576   # no file written by a case grows beyond 1 GiB (disk guard for streamed outputs)

msg_of() { # first "error" line of stderr, else its first line
  local m; m=$(grep -m1 -a '^error' "$1"); [ -n "$m" ] || m=$(grep -a -v '^[0-9]*$' "$1" | head -n1)
  printf '%s' "$m" | tr '\t\r' '  ' | cut -c1-120
}
run() { # class, case, command...
  local g=$1 c=$2; shift 2
  local t0 t1 rc
  t0=$(date +%s.%N)
  /usr/bin/time -f %M -o rss.txt $PIN timeout -k 2 "$TO" prlimit --as=2000000000 -- "$@" > out.txt 2> err.txt < /dev/null
  rc=$?
  t1=$(date +%s.%N)
  printf '%s\t%s\t%s\t%s\t%.2f\t%s\n' "$g" "$c" "$rc" "$(msg_of err.txt)" "$(echo "$t1 - $t0" | bc)" "$(tail -n1 rss.txt | grep -o '^[0-9]*$')"
}
note() { # class, case, exit, message (a check made by the script, not a command)
  printf '%s\t%s\t%s\t%s\t0\t\n' "$1" "$2" "$3" "$4"
}
same() { # class, case, file, reference copy: 0 when byte-identical (or both absent)
  if cmp -s "$3" "$4"; then note "$1" "$2" 0 "left byte-identical"
  else note "$1" "$2" 1 "CHANGED: now begins '$(head -c 40 "$3" 2>/dev/null | tr '\n\t' '  ')'"; rm -f "$3"; cp "$4" "$3"; fi
}
kind() { if [ -L "$1" ]; then echo symlink; elif [ -p "$1" ]; then echo fifo; elif [ -d "$1" ]; then echo dir; elif [ -c "$1" ]; then echo chardev; elif [ -f "$1" ]; then echo "file $(stat -c %s "$1")B"; else echo absent; fi; }
still() { # class, case, path, expected kind
  local k; k=$(kind "$3"); if [ "$k" = "$4" ]; then note "$1" "$2" 0 "still $k"; else note "$1" "$2" 1 "NOW $k (was $4)"; fi
}
endless_fifo() { # path, header line, repeated line: a FIFO whose writer never stops
  rm -f "$1"; mkfifo "$1"
  ( printf '%s\n' "$2"; yes "$3" ) > "$1" 2>/dev/null &
  BG+=($!)
}
stop_bg() { for p in "${BG[@]}"; do kill "$p" 2>/dev/null; done; BG=(); }

printf 'class\tcase\texit\tmessage\tseconds\tpeak_rss_kb\n'

# ---------------------------------------------------------------- inputs
CIRCLE='x_mm,y_mm,z_mm\n1,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0.7071067811865476,0.7071067811865476,0\n'
printf "$CIRCLE" > c.csv
printf 'axis,position_mm,pos_um,str1_um,str2_um,pitch_urad,yaw_urad,roll_urad\nx,-1000,0,0,0,0,0,0\nx,1000,0,0,0,0,0,0\ny,-1000,0,0,0,0,0,0\ny,1000,0,0,0,0,0,0\nz,-1000,0,0,0,0,0,0\nz,1000,0,0,0,0,0,0\n' > map.csv
printf '[squareness]\nxy_urad = 1\nxz_urad = 0\nyz_urad = 0\n' > sq.toml
printf 'id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,0\nT3,0,1000,0\n' > tref.csv
printf 'id,x_mm,y_mm,z_mm\nT1,1,0,0\nT2,1001,0,0\nT3,1,1000,0\n' > tmeas.csv
printf 'G90\nG0 X1 Y2 Z3\nG1 X10 Y10 Z0 F100\n' > prog.nc
printf 'b_deg,c_deg,x_mm,y_mm,z_mm\n0,0,1,2,3\n0,90,4,5,6\n' > head.csv
printf 'id,x_mm,y_mm,z_mm\nA,10,20,0\n' > holes.csv
"$T" simulate load --out sload > /dev/null 2>&1
"$T" simulate scan --out sscan --features 2 > /dev/null 2>&1
"$T" simulate latency --out slat > /dev/null 2>&1
"$T" simulate somac --out ssomac --holes-per-row 2 > /dev/null 2>&1
"$T" load map --bed sload/bed.toml --output lmap.csv > /dev/null 2>&1
cat > part.toml <<'EOF'
[[plane]]
id = "top"
point_mm = [50.0, 50.0, 50.0]
normal = [0.0, 0.0, 1.0]

[[cylinder]]
id = "bore"
point_mm = [50.0, 50.0, 0.0]
axis = [0.0, 0.0, 1.0]
diameter_mm = 50.0
side = "inside"
EOF
cat > prog.dms <<'EOF'
DMISMN/ 'AUDIT31'
UNITS/ MM, ANGDEC
D(START) = DATSET/MCS
GOTO/50.0, 50.0, 175.0
S(PROBE6) = SNSDEF/PROBE, FIXED, CART, 0.0, 0.0, 30.0, 0.0, 0.0, -1.0, 4.0
SNSLCT/S(PROBE6)
GOTO/50.0, 50.0, 75.0
F(C1) = FEAT/CIRCLE,INNER,CART, 50.0, 50.0, 40.0, 0.0, 0.0, 1.0, 50.0
MEAS/CIRCLE,F(C1),4
PTMEAS/CART, 75.0, 50.0, 40.0, -1.0,  0.0, 0.0
PTMEAS/CART, 25.0, 50.0, 40.0,  1.0,  0.0, 0.0
PTMEAS/CART, 50.0, 75.0, 40.0,  0.0, -1.0, 0.0
PTMEAS/CART, 50.0, 25.0, 40.0,  0.0,  1.0, 0.0
ENDMES
GOTO/ 50.0, 50.0, 100.0
OUTPUT/FA(C1)
ENDFIL
EOF
qif() { # file, characteristics inner xml (after <Characteristics>), [namespace], [units xml]
  local ns=${3:-http://qifstandards.org/xsd/qif3}
  local units=${4:-'<FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>mm</UnitName><UnitConversion><Factor>0.001</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>'}
  printf '<?xml version="1.0"?>\n<QIFDocument xmlns="%s" versionQIF="3.0.0">\n%s\n<Characteristics>\n%s\n</Characteristics>\n</QIFDocument>\n' "$ns" "$units" "$2" > "$1"
}
DIAM='<CharacteristicDefinitions n="1"><DiameterCharacteristicDefinition id="2"><Tolerance><MaxValue>0.006</MaxValue><MinValue>-0.001</MinValue><DefinedAsLimit>LIM</DefinedAsLimit></Tolerance></DiameterCharacteristicDefinition></CharacteristicDefinitions>'
NOM='<CharacteristicNominals n="1"><DiameterCharacteristicNominal id="3"><CharacteristicDefinitionId>2</CharacteristicDefinitionId><TargetValue>2</TargetValue></DiameterCharacteristicNominal></CharacteristicNominals>'
qif good.qif "${DIAM//LIM/false}$NOM"

# ---------------------------------------------------------------- 1. crashes and huge counts
python3 - <<'PY'
ns = 'http://qifstandards.org/xsd/qif3'
def doc(body, pre=''):
    return f'<?xml version="1.0"?>\n{pre}<QIFDocument xmlns="{ns}">\n{body}</QIFDocument>\n'
open('deep256.qif', 'w').write(doc('<a>' * 254 + '</a>' * 254))            # 255 deep with the root
open('deep257.qif', 'w').write(doc('<a>' * 257 + '</a>' * 257))
open('deepchar.qif', 'w').write(doc('<Characteristics>' + '<b x="1">' * 100000 + '</b>' * 100000 + '</Characteristics>'))
open('unclosed.qif', 'w').write(doc('<a>' * 1000000))
open('selfclose.qif', 'w').write(doc('<a/>' * 5000000))                      # 5 M nodes, 20 MB
open('longattr.qif', 'w').write(doc('<a v="' + 'x' * 60_000_000 + '"/>'))
open('longtext.qif', 'w').write(doc('<Characteristics><t>' + '1' * 50_000_000 + '</t></Characteristics>'))
lol = '<!DOCTYPE QIFDocument [<!ENTITY l0 "lolololololol">' + ''.join(
    f'<!ENTITY l{i} "{("&l%d;" % (i - 1)) * 10}">' for i in range(1, 10)) + ']>\n'
open('laughs.qif', 'w').write(doc('<Characteristics><t>&l9;</t></Characteristics>', lol))
open('extent.qif', 'w').write(doc('<Characteristics><t>&x;</t></Characteristics>',
     '<!DOCTYPE QIFDocument [<!ENTITY x SYSTEM "file:///dev/zero">]>\n'))
open('manyattrs.qif', 'w').write(doc('<a ' + ' '.join(f'a{i}="1"' for i in range(500000)) + '/>'))
open('deepcomment.qif', 'w').write(doc('<!--' + '<a>' * 1000000 + '-->'))
open('deepcdata.qif', 'w').write(doc('<t><![CDATA[' + '<a>' * 1000000 + ']]></t>'))
PY
for q in deep256 deep257 deepchar unclosed selfclose longattr longtext laughs extent manyattrs deepcomment deepcdata; do
  run crash "fit circle --qif-plan $q.qif" "$T" fit circle c.csv --qif-plan $q.qif
done
run crash "somac inspect --points 10001 (limit+1)" "$T" somac inspect --holes holes.csv --diameter-mm 6 --points 10001 --db a1.sqlite
run crash "somac inspect --points 3" "$T" somac inspect --holes holes.csv --diameter-mm 6 --points 3 --db a1.sqlite
run crash "somac inspect --points 18446744073709551615" "$T" somac inspect --holes holes.csv --diameter-mm 6 --points 18446744073709551615 --db a1.sqlite
run crash "somac inspect --points 10000 (at limit)" "$T" somac inspect --holes holes.csv --diameter-mm 6 --points 10000 --db a1.sqlite
run crash "probe sphere --points 1e9" "$T" probe sphere --near=0,0,0 --diameter-mm 25 --points 1000000000
run crash "probe sphere --points 4" "$T" probe sphere --near=0,0,0 --diameter-mm 25 --points 4
run crash "latency probe --points 1e9" "$T" latency probe --near=0,0,0 --diameter-mm 25 --points 1000000000
run crash "latency probe --feeds-mm-min 20000 feeds" "$T" latency probe --near=0,0,0 --diameter-mm 25 --feeds-mm-min "$(seq -s, 1 20000)"
run crash "head-offset acquire --points 1e9" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation 0,0 --points 1000000000 --output ha.csv
run crash "head-offset acquire 20000 orientations" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 $(for i in $(seq 1 20000); do printf -- '--orientation 0,%s ' $((i % 360)); done) --table-center-mm 0,0,0 --output ha.csv
run crash "kinematics calibrate --points 1e9" "$T" kinematics calibrate --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --orientation 0,0 --orientation 0,120 --orientation 90,0 --points 1000000000
run crash "probe sphere --monte-carlo-runs 1e9" bash -c "printf '[iso10360]\nmpe_e_um = [2, 300]\nmpe_p_um = 2\n' > mm.toml; exec '$T' probe sphere --near=0,0,0 --diameter-mm 25 --machine-model mm.toml --monte-carlo-runs 1000000000"
run crash "scan plan --dt-s 1e-12" "$T" scan plan --features sscan/features.toml --output sp.csv --dt-s 1e-12
run crash "scan plan --dt-s 0" "$T" scan plan --features sscan/features.toml --output sp.csv --dt-s 0
run crash "scan run --scan-speed-mm-s 1e-9" "$T" scan run --features sscan/features.toml --output sr.csv --scan-speed-mm-s 1e-9
run crash "scan plan --scan-speed-mm-s 1e-9" "$T" scan plan --features sscan/features.toml --output sp.csv --scan-speed-mm-s 1e-9
run crash "scan plan --accel-mm-s2 1e-9" "$T" scan plan --features sscan/features.toml --output sp.csv --accel-mm-s2 1e-9
run crash "simulate scan --features 201" "$T" simulate scan --out ss201 --features 201
run crash "simulate somac --holes-per-row 2001" "$T" simulate somac --out sso --holes-per-row 2001
run crash "load map --element-size-mm 0.01" "$T" load map --bed sload/bed.toml --output lm.csv --element-size-mm 0.01
run crash "load deflection --element-size-mm 1e-6" "$T" load deflection --bed sload/bed.toml --load sload/load.toml --at sload/points.csv --element-size-mm 1e-6
run crash "load map [grid] spacing_mm = 0.001" bash -c "sed 's/^spacing_mm = .*/spacing_mm = 0.001/' sload/bed.toml > bg.toml; exec '$T' load map --bed bg.toml --output lm.csv"
run crash "load map [portal] y_step_mm = 1e-9" bash -c "sed 's/^y_step_mm = .*/y_step_mm = 1e-9/' sload/bed.toml > by.toml; exec '$T' load map --bed by.toml --output lm.csv"
run crash "comp correct --decimals 1000000000" "$T" comp correct --map map.csv --points c.csv --output cc.csv --decimals 1000000000
run crash "orient --decimals 4294967295" "$T" orient --reference tref.csv --measured tmeas.csv --program prog.nc --output o.nc --decimals 4294967295
printf 'G17 G90\nG0 X0 Y0 Z0\nG2 X10 Y0 I5 J0 F100\n' > arc.nc
printf 'id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,0\nT3,0,1000,0\nT4,0,0,1000\n' > tref4.csv
printf 'id,x_mm,y_mm,z_mm\nT1,0,0,0\nT2,1000,0,17.45\nT3,0,1000,0\nT4,-17.45,0,1000\n' > ttilt4.csv
run crash "orient --arc-tolerance-mm 1e-300 (tilted arc)" "$T" orient --reference tref4.csv --measured ttilt4.csv --program arc.nc --output o.nc --arc-tolerance-mm 1e-300
run crash "orient --arc-tolerance-mm 1e-9 (tilted arc)" "$T" orient --reference tref4.csv --measured ttilt4.csv --program arc.nc --output o.nc --arc-tolerance-mm 1e-9
run crash "latency --max-delay-s 1e9" "$T" latency --machine slat/machine.csv --probe slat/probe.csv --method scan --max-delay-s 1e9
TO=3 run crash "ippdme serve --write-timeout-s 1e300 (3 s)" "$T" ippdme serve --port 0 --write-timeout-s 1e300
printf 'G0 X0 Y0 Z0\n' > big_n.nc; yes 'G1 X1' | head -n 5000000 >> big_n.nc
run crash "orient 5 M-line G-code (30 MB)" "$T" orient --reference tref.csv --measured tmeas.csv --program big_n.nc --output o.nc

# ---------------------------------------------------------------- 2. unbounded reads
ln -sf /dev/urandom rnd.parquet; ln -sf /dev/zero zero.parquet; ln -sf /dev/urandom rnd.e57; ln -sf /dev/zero zero.e57
# text inputs of every command, each given /dev/urandom, a 3 GB sparse file and an endless FIFO
run unbounded "fit sphere /dev/urandom" "$T" fit sphere /dev/urandom
run unbounded "fit sphere 3 GB sparse .csv" "$T" fit sphere sparse.csv
run unbounded "fit sphere 3 GB sparse .ds" "$T" fit sphere sparse.ds
endless_fifo fifo.csv 'x_mm,y_mm,z_mm' '1,2,3'
run unbounded "fit sphere endless FIFO (valid rows)" "$T" fit sphere fifo.csv; stop_bg
endless_fifo fifo.ds '1000000000000' '1 2 3'
run unbounded "fit sphere endless FIFO .ds (count 1e12)" "$T" fit sphere fifo.ds; stop_bg
{ echo x_mm,y_mm,z_mm; yes 1,2,3 | head -n 100000000; } > big600.csv
run unbounded "fit sphere 600 MB valid CSV (within the 2 GiB input limit)" "$T" fit sphere big600.csv; rm -f big600.csv
endless_fifo fifo2.csv 'x_mm,y_mm,z_mm' '1,2,3'
run unbounded "comp correct endless FIFO (streamed, output 1 GiB cap)" "$T" comp correct --map map.csv --points fifo2.csv --output cf.csv; stop_bg; rm -f cf.csv
endless_fifo fifo3.csv 'id,x_mm,y_mm,z_mm' 'A,1,2,3'
run unbounded "align --from endless FIFO" "$T" align --from fifo3.csv --to tref.csv; stop_bg
run unbounded "comp correct --map /dev/urandom" "$T" comp correct --map /dev/urandom --points c.csv --output cc.csv
run unbounded "comp correct --squareness 3 GB sparse .toml" "$T" comp correct --map map.csv --squareness sparse.toml --points c.csv --output cc.csv
run unbounded "comp correct --squareness /dev/zero" "$T" comp correct --map map.csv --squareness /dev/zero --points c.csv --output cc.csv
endless_fifo fifo.toml '[squareness]' '# x'
run unbounded "comp correct --squareness endless FIFO" "$T" comp correct --map map.csv --squareness fifo.toml --points c.csv --output cc.csv; stop_bg
run unbounded "comp correct --points 3 GB sparse .parquet" "$T" comp correct --map map.csv --points sparse.parquet --output cc.csv
run unbounded "fit sphere /dev/urandom as .parquet" "$T" fit sphere rnd.parquet
run unbounded "fit sphere /dev/zero as .parquet" "$T" fit sphere zero.parquet
run unbounded "fit sphere 3 GB sparse .e57" "$T" fit sphere sparse.e57
run unbounded "fit sphere /dev/urandom as .e57" "$T" fit sphere rnd.e57
run unbounded "fit sphere /dev/zero as .e57" "$T" fit sphere zero.e57
rm -f fifo.parquet; mkfifo fifo.parquet; ( yes PAR1 > fifo.parquet ) 2>/dev/null & BG+=($!)
run unbounded "fit sphere endless FIFO .parquet" "$T" fit sphere fifo.parquet; stop_bg
rm -f fifo.e57; mkfifo fifo.e57; ( yes ASTM-E57 > fifo.e57 ) 2>/dev/null & BG+=($!)
run unbounded "fit sphere endless FIFO .e57" "$T" fit sphere fifo.e57; stop_bg
run unbounded "load curves --load /dev/urandom" "$T" load curves --map lmap.csv --load /dev/urandom
run unbounded "load curves --load 3 GB sparse" "$T" load curves --map lmap.csv --load sparse.toml
run unbounded "load map --bed /dev/zero" "$T" load map --bed /dev/zero --output lm.csv
endless_fifo fifo_bed.toml '[bed]' '# x'
run unbounded "load map --bed endless FIFO" "$T" load map --bed fifo_bed.toml --output lm.csv; stop_bg
run unbounded "load curves --map 3 GB sparse" "$T" load curves --map sparse.csv --load sload/load.toml
run unbounded "scan plan --features /dev/urandom" "$T" scan plan --features /dev/urandom --output sp.csv
run unbounded "scan plan --features 3 GB sparse" "$T" scan plan --features sparse.toml --output sp.csv
run unbounded "scan run --part (truth.json) 3 GB sparse" "$T" scan run --features sscan/features.toml --part sparse.json --output sr.csv
endless_fifo fifo.json '{"features": [' '{"id": "x"},'
run unbounded "scan run --part endless FIFO json" "$T" scan run --features sscan/features.toml --part fifo.json --output sr.csv; stop_bg
run unbounded "scan run --machine /dev/zero" "$T" scan run --features sscan/features.toml --machine /dev/zero --output sr.csv
run unbounded "orient --program /dev/urandom" "$T" orient --reference tref.csv --measured tmeas.csv --program /dev/urandom --output o.nc
run unbounded "orient --program 3 GB sparse" "$T" orient --reference tref.csv --measured tmeas.csv --program sparse.nc --output o.nc
endless_fifo fifo.nc 'G90' 'G1 X1 Y2 Z3'
run unbounded "orient --program endless FIFO" "$T" orient --reference tref.csv --measured tmeas.csv --program fifo.nc --output o.nc; stop_bg; rm -f o.nc
run unbounded "somac run --program 3 GB sparse" "$T" somac run --program sparse.nc --cell ssomac/cell.toml --db s1.sqlite
run unbounded "somac run --cell /dev/urandom" "$T" somac run --program ssomac/program.nc --cell /dev/urandom --db s1.sqlite
endless_fifo fifo2.nc '%' 'G1 X1000 Y1900 Z5 F1500 (MSG,Measure SOMaC)'
run unbounded "somac inspect --program endless FIFO" "$T" somac inspect --program fifo2.nc --diameter-mm 6 --db s1.sqlite; stop_bg
run unbounded "somac inspect --holes /dev/zero" "$T" somac inspect --holes /dev/zero --diameter-mm 6 --db s1.sqlite
run unbounded "dmis run /dev/urandom" "$T" dmis run /dev/urandom --part part.toml --db d1.sqlite --output dz.dms
run unbounded "dmis run 3 GB sparse .dms" "$T" dmis run sparse.dms --part part.toml --db d1.sqlite
endless_fifo fifo.dms 'DMISMN/ '"'"'X'"'"'' 'GOTO/50.0, 50.0, 175.0'
run unbounded "dmis run endless FIFO" "$T" dmis run fifo.dms --part part.toml --db d1.sqlite --output df.dms; stop_bg
run unbounded "dmis run --part 3 GB sparse" "$T" dmis run prog.dms --part sparse.toml --db d1.sqlite
run unbounded "dmis run --machine /dev/urandom" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --machine /dev/urandom --db d1.sqlite
run unbounded "fit --qif-plan /dev/urandom" "$T" fit circle c.csv --qif-plan /dev/urandom
run unbounded "fit --qif-plan 3 GB sparse" "$T" fit circle c.csv --qif-plan sparse.qif
endless_fifo fifo.qif '<QIFDocument xmlns="http://qifstandards.org/xsd/qif3">' '<a>x</a>'
run unbounded "fit --qif-plan endless FIFO" "$T" fit circle c.csv --qif-plan fifo.qif; stop_bg
run unbounded "probe sphere --machine-model /dev/zero" "$T" probe sphere --near=0,0,0 --diameter-mm 25 --machine-model /dev/zero
run unbounded "probe sphere --machine-model 3 GB sparse" "$T" probe sphere --near=0,0,0 --diameter-mm 25 --machine-model sparse.toml
TO=4 run unbounded "ippdme serve --part /dev/urandom" "$T" ippdme serve --port 0 --part /dev/urandom
TO=4 run unbounded "ippdme serve --part 3 GB sparse" "$T" ippdme serve --port 0 --part sparse.toml
endless_fifo fifo_part.toml '[[sphere]]' '# x'
TO=4 run unbounded "ippdme serve --part endless FIFO" "$T" ippdme serve --port 0 --part fifo_part.toml; stop_bg
TO=4 run unbounded "ippdme serve --machine /dev/zero" "$T" ippdme serve --port 0 --machine /dev/zero
run unbounded "latency --machine /dev/urandom" "$T" latency --machine /dev/urandom --probe slat/probe.csv
run unbounded "head-offset --points 3 GB sparse" "$T" head-offset --points sparse.csv
run unbounded "audit list --db /dev/urandom" "$T" audit list --db /dev/urandom
run unbounded "audit verify --db 3 GB sparse" "$T" audit verify --db sparse.csv

# ---------------------------------------------------------------- 3. binary inputs with the wrong meaning
SEED_E57=${SEED_E57:-$REPO/fuzz/seeds/e57_points/doubles.e57}
cat > e57mk.py <<'PY'
#!/usr/bin/env python3
"""Rewrite the truepos fuzz seed doubles.e57 with a changed XML section and/or changed point bytes.
usage: e57mk.py SEED OUT [--pose w,x,y,z,tx,ty,tz] [--count N] [--patch OLDFLOAT=NEWHEX] [--xmlsub OLD=NEW] [--badcrc]"""
import struct, sys
def crc32c(b, _t=[]):
    if not _t:
        for i in range(256):
            c = i
            for _ in range(8): c = (c >> 1) ^ 0x82F63B78 if c & 1 else c >> 1
            _t.append(c)
    c = 0xFFFFFFFF
    for x in b: c = _t[(c ^ x) & 0xFF] ^ (c >> 8)
    return c ^ 0xFFFFFFFF
a = sys.argv[1:]; seed, out = a[0], a[1]; opts = a[2:]
d = open(seed, 'rb').read()
sig, ma, mi, flen, xoff, xlen, ps = struct.unpack('<8sIIQQQQ', d[:48])
log = bytearray(b''.join(d[i:i+ps-4] for i in range(0, len(d), ps)))
lx = xoff // ps * (ps - 4) + xoff % ps
xml = log[lx:lx+xlen].decode()
binpart = log[:lx]
badcrc = False
i = 0
while i < len(opts):
    o = opts[i]
    if o == '--pose':
        w,x,y,z,tx,ty,tz = opts[i+1].split(','); i += 1
        pose = ('<pose type="Structure"><rotation type="Structure"><w type="Float">%s</w><x type="Float">%s</x><y type="Float">%s</y><z type="Float">%s</z></rotation>'
                '<translation type="Structure"><x type="Float">%s</x><y type="Float">%s</y><z type="Float">%s</z></translation></pose>\n') % (w,x,y,z,tx,ty,tz)
        xml = xml.replace('<cartesianBounds', pose + '<cartesianBounds', 1)
    elif o == '--count':
        import re; xml = re.sub(r'recordCount="\d+"', 'recordCount="%s"' % opts[i+1], xml, count=1); i += 1
    elif o == '--xmlsub':
        old, new = opts[i+1].split('=', 1); assert old in xml, old; xml = xml.replace(old, new, 1); i += 1
    elif o == '--patch':
        old, new = opts[i+1].split('='); ob = struct.pack('<d', float(old)); nb = bytes.fromhex(new)
        k = binpart.find(ob); assert k >= 0, old; binpart[k:k+8] = nb; i += 1
    elif o == '--badcrc':
        badcrc = True
    i += 1
xb = xml.encode()
logical = bytes(binpart) + xb
pages = []
for k in range(0, len(logical), ps - 4):
    chunk = logical[k:k+ps-4].ljust(ps - 4, b'\0')
    pages.append(chunk)
phys_x = lx // (ps - 4) * ps + lx % (ps - 4)
hdr = struct.pack('<8sIIQQQQ', sig, ma, mi, len(pages) * ps, phys_x, len(xb), ps)
pages[0] = hdr + pages[0][48:]
outb = bytearray()
for p in pages:
    outb += p + struct.pack('>I', crc32c(p))
if badcrc: outb[60] ^= 0x01
open(out, 'wb').write(outb)
PY
if python3 -c 'import pyarrow' 2>/dev/null; then
python3 - <<'PY'
import datetime, decimal, struct
import pyarrow as pa, pyarrow.parquet as pq
D = decimal.Decimal
rows = [(11.0, 2.0, 3.0), (-9.0, 2.0, 3.0), (1.0, 12.0, 3.0), (1.0, -8.0, 3.0), (1.0, 2.0, 13.0)]
def cols(t=pa.float64()):
    return {n: pa.array([r[i] for r in rows], t) for i, n in enumerate(('x_mm', 'y_mm', 'z_mm'))}
def w(name, table, **kw):
    kw.setdefault('store_schema', False)
    try:
        pq.write_table(table, name, **kw)
    except Exception as e:  # a pyarrow that cannot write this one: the case then reads a missing file
        print(f'pyarrow: {name}: {e}', file=__import__('sys').stderr)
base = cols()
w('ok.parquet', pa.table(base), compression='NONE', use_dictionary=False, write_page_checksum=True)
# decimals: FIXED_LEN_BYTE_ARRAY (38 digits), INT64, a huge one, decimal256
w('dec38.parquet', pa.table({**base, 'x_mm': pa.array([D('11.0000000001'), D('-9'), D('1'), D('1'), D('1')], pa.decimal128(38, 10))}))
w('dec18.parquet', pa.table({**base, 'x_mm': pa.array([D('11.000'), D('-9'), D('1'), D('1'), D('1')], pa.decimal128(18, 3))}), store_decimal_as_integer=True)
w('dechuge.parquet', pa.table({**base, 'x_mm': pa.array([D('1e30'), D('-9'), D('1'), D('1'), D('1')], pa.decimal128(38, 0))}))
w('dec256.parquet', pa.table({**base, 'x_mm': pa.array([D('11'), D('-9'), D('1'), D('1'), D('1')], pa.decimal256(60, 5))}))
w('decneg.parquet', pa.table({**base, 'x_mm': pa.array([D('11.000'), D('-9'), D('1'), D('1'), D('1')], pa.decimal128(9, 3))}), store_decimal_as_integer=True, write_page_checksum=True)  # INT32 decimal with CRCs
# unsigned 64 at its maximum, int64 beyond 2^53
w('u64.parquet', pa.table({**base, 'x_mm': pa.array([2**64 - 1, 0, 1, 1, 1], pa.uint64())}))
w('i64.parquet', pa.table({**base, 'x_mm': pa.array([2**53 + 1, -9, 1, 1, 1], pa.int64())}))
# times and others that are not lengths
w('ts.parquet', pa.table({**base, 'x_mm': pa.array([datetime.datetime(2026, 1, 1)] * 5, pa.timestamp('ns'))}))
w('ts96.parquet', pa.table({**base, 'x_mm': pa.array([datetime.datetime(2026, 1, 1)] * 5, pa.timestamp('ns'))}), use_deprecated_int96_timestamps=True)
w('time.parquet', pa.table({**base, 'x_mm': pa.array([1, 2, 3, 4, 5], pa.time32('ms'))}))
w('dur.parquet', pa.table({**base, 'x_mm': pa.array([1, 2, 3, 4, 5], pa.duration('s'))}))
w('f16.parquet', pa.table({**base, 'x_mm': pa.array([11.0, -9.0, 1.0, 1.0, 1.0], pa.float16())}))
w('str.parquet', pa.table({**base, 'x_mm': pa.array(['11', '-9', '1', '1', '1'])}))
w('bool.parquet', pa.table({**base, 'x_mm': pa.array([True, False, True, True, True])}))
w('null.parquet', pa.table({**base, 'x_mm': pa.array([11.0, None, 1.0, 1.0, 1.0], pa.float64())}))
w('nan.parquet', pa.table({**base, 'x_mm': pa.array([11.0, float('nan'), 1.0, 1.0, 1.0])}))
w('inf.parquet', pa.table({**base, 'x_mm': pa.array([11.0, float('inf'), 1.0, 1.0, 1.0])}))
w('dict.parquet', pa.table({**base, 'x_mm': pa.array([11.0, -9.0, 1.0, 1.0, 1.0]).dictionary_encode()}))
w('list.parquet', pa.table({'x_mm': pa.array([[11.0], [-9.0], [1.0], [1.0], [1.0]]), 'y_mm': base['y_mm'], 'z_mm': base['z_mm']}))
w('map.parquet', pa.table({'x_mm': pa.array([[('a', 1.0)]] * 5, pa.map_(pa.string(), pa.float64())), 'y_mm': base['y_mm'], 'z_mm': base['z_mm']}))
w('case.parquet', pa.table({'X_MM': base['x_mm'], 'x_mm': base['x_mm'], 'y_mm': base['y_mm'], 'z_mm': base['z_mm']}))
t = pa.Table.from_arrays([base['x_mm'], base['y_mm'], base['z_mm'], pa.array([0.0] * 5)], names=['x_mm', 'y_mm', 'z_mm', 'z_mm'])
w('dupz.parquet', t)
w('empty.parquet', pa.table({n: pa.array([], pa.float64()) for n in ('x_mm', 'y_mm', 'z_mm')}))
w('rg1.parquet', pa.table(base), row_group_size=1)
w('nocols.parquet', pa.table({'a': pa.array([1.0])}))
# corruptions of ok.parquet (no dictionary, no compression, CRC-32 on pages)
ok = open('ok.parquet', 'rb').read()
open('trunc.parquet', 'wb').write(ok[:-30])
open('truncmid.parquet', 'wb').write(ok[:len(ok) // 2] + ok[-8:])
flen = struct.unpack('<I', ok[-8:-4])[0]
open('footlen.parquet', 'wb').write(ok[:-8] + struct.pack('<I', 0xFFFFFFF0) + b'PAR1')
open('footlen0.parquet', 'wb').write(ok[:-8] + struct.pack('<I', 0) + b'PAR1')
# the CRC field itself changed (values intact)
xb = struct.pack('<5d', 11.0, -9.0, 1.0, 1.0, 1.0); k = ok.find(xb)
b = bytearray(ok); b[k - 1] ^= 0xFF; open('crcbyte.parquet', 'wb').write(b)
# a value flipped in a page written without CRC
w('nocrc.parquet', pa.table(base), compression='NONE', use_dictionary=False)
nc = bytearray(open('nocrc.parquet', 'rb').read()); k = nc.find(xb); nc[k + 8] ^= 1
open('nocrcflip.parquet', 'wb').write(nc)
# num_values of the first page header doubled (a page that claims 10 values of 5)
b = bytearray(ok); k = ok.find(b'\x15\x0a', 4)
if k > 0: b[k + 1] = 0x14
open('numvals.parquet', 'wb').write(b)
# CSV text named .parquet
open('text.parquet', 'w').write('x_mm,y_mm,z_mm\n1,2,3\n')
PY
for f in dec38 dec18 dechuge dec256 decneg u64 i64 ts ts96 time dur f16 str bool null nan inf dict list map case dupz empty rg1 nocols trunc truncmid footlen footlen0 crcbyte nocrcflip numvals text; do
  run binary "fit sphere $f.parquet" "$T" fit sphere $f.parquet --json
  case $f in dec18|decneg|u64|i64|nocrcflip|rg1|dict|f16) note binary "  $f.parquet JSON" 0 "$(tr -d ' \n' < out.txt | grep -o '"center_mm":\[[^]]*\]' | head -1 | cut -c1-110)";; esac
done
run binary "comp correct dupz.parquet" "$T" comp correct --map map.csv --points dupz.parquet --output dz.csv
run binary "comp correct u64.parquet -> parquet" "$T" comp correct --map map.csv --points u64.parquet --output u64o.parquet
run binary "comp correct numvals.parquet (streamed)" "$T" comp correct --map map.csv --points numvals.parquet --output nv.csv
else
  note binary "parquet cases" 0 "SKIPPED: no pyarrow"
fi
# E57 from the fuzz seed (6 points in metres on a line: x = 0 … 0.0075, y = 0 … -0.005, z = 0.0125)
if [ -f "$SEED_E57" ]; then
e57() { python3 e57mk.py "$SEED_E57" "$@"; }
e57 q_zero.e57 --pose 0,0,0,0,0,0,0
e57 q_neg.e57 --pose -1,0,0,0,0,0,0
e57 q_two.e57 --pose 2,0,0,0,0,0,0
e57 q_nan.e57 --pose NaN,0,0,0,0,0,0
e57 q_inftxt.e57 --pose inf,0,0,0,0,0,0
e57 q_1e400.e57 --pose 1e400,0,0,0,0,0,0
e57 q_tiny.e57 --pose 1e-200,0,0,0,0,0,0
e57 t_huge.e57 --pose 1,0,0,0,1e300,0,0
e57 t_far.e57 --pose 1,0,0,0,1e10,0,0
e57 t_word.e57 --pose 1,0,0,0,abc,0,0
e57 q_half.e57 --pose 0.5,0.5,0.5,0.5000001,0,0,0
e57 cnt_huge.e57 --count 1000000000000000
e57 cnt_more.e57 --count 7
e57 cnt_less.e57 --count 2
e57 cnt_zero.e57 --count 0
e57 pt_nan.e57 --patch 0.0075=000000000000f87f
e57 pt_inf.e57 --patch 0.0075=000000000000f07f
e57 pt_huge.e57 --patch 0.0075=ffffffffffffef7f
e57 pt_denorm.e57 --patch 0.0075=0100000000000000
e57 badcrc.e57 --badcrc
e57 badxml.e57 --xmlsub '</e57Root>=</e57Rot>'
e57 offset.e57 --xmlsub 'fileOffset="48"=fileOffset="999999999999"'
e57 proto_int.e57 --xmlsub '<cartesianX type="Float">0</cartesianX>=<cartesianX type="Integer" minimum="0" maximum="0"/>'
e57 nox.e57 --xmlsub '<cartesianX type="Float">0</cartesianX>='
head -c 1500 q_neg.e57 > trunc.e57
for f in q_zero q_neg q_two q_nan q_inftxt q_1e400 q_tiny t_huge t_far t_word q_half cnt_huge cnt_more cnt_less cnt_zero pt_nan pt_inf pt_huge pt_denorm badcrc badxml offset proto_int nox trunc; do
  run binary "fit line $f.e57" "$T" fit line $f.e57 --json
  case $f in q_neg|q_half|cnt_less|pt_denorm|proto_int) note binary "  $f.e57 JSON" 0 "$(tr -d ' \n' < out.txt | cut -c1-110)";; esac
done
run binary "comp correct pt_nan.e57 (dropped named)" "$T" comp correct --map map.csv --points pt_nan.e57 --output e57o.csv
run binary "comp correct t_huge.e57" "$T" comp correct --map map.csv --points t_huge.e57 --output e57o.csv
run binary "load correct q_zero.e57" "$T" load correct --map lmap.csv --load sload/load.toml --bed sload/bed.toml --points q_zero.e57 --output e57l.csv
else
  note binary "e57 cases" 0 "SKIPPED: no seed $SEED_E57"
fi

# ---------------------------------------------------------------- 4. fits whose answer is not determined
python3 - <<'PY'
import math, random
def w(name, pts):
    open(name, 'w').write('x_mm,y_mm,z_mm\n' + ''.join('%r,%r,%r\n' % p for p in pts))
random.seed(31)
w('p1.csv', [(1.0, 2.0, 3.0)])
w('p2.csv', [(0.0, 0.0, 0.0), (1.0, 1.0, 1.0)])
w('plane3.csv', [(0.0, 0.0, 0.0), (10.0, 0.0, 1.0), (0.0, 10.0, 2.0)])
w('circle3.csv', [(5.0, 0.0, 0.0), (0.0, 5.0, 0.0), (-5.0, 0.0, 0.0)])
w('sphere4.csv', [(5.0, 0.0, 0.0), (0.0, 5.0, 0.0), (-5.0, 0.0, 0.0), (0.0, 0.0, 5.0)])
w('sphere3.csv', [(5.0, 0.0, 0.0), (0.0, 5.0, 0.0), (-5.0, 0.0, 0.0)])
w('sphere_coplanar.csv', [(5 * math.cos(a), 5 * math.sin(a), 0.0) for a in [i * 0.5 for i in range(12)]])
w('sphere_cap.csv', [(20 * math.sin(0.001) * math.cos(a), 20 * math.sin(0.001) * math.sin(a), 20 * math.cos(0.001)) for a in [i * 0.7 for i in range(9)]] + [(0.0, 0.0, 20.0)])
w('cyl_ring.csv', [(5 * math.cos(a), 5 * math.sin(a), 0.0) for a in [i * 0.4 for i in range(15)]])
w('cyl_line.csv', [(0.0, 0.0, float(i)) for i in range(10)])
w('cyl6.csv', [(5 * math.cos(a), 5 * math.sin(a), z) for a, z in [(0.1, 0), (1.3, 3), (2.4, 7), (3.5, 1), (4.6, 9), (5.7, 4)]])
w('cone_cyl.csv', [(5 * math.cos(a), 5 * math.sin(a), z) for a in [i * 0.7 for i in range(9)] for z in (0.0, 10.0)])
w('cone_2rings.csv', [((5 + z * 0.2) * math.cos(a), (5 + z * 0.2) * math.sin(a), z) for a in [i * 0.7 for i in range(9)] for z in (0.0, 10.0)])
w('cone7.csv', [((5 + z * 0.2) * math.cos(a), (5 + z * 0.2) * math.sin(a), z) for a, z in [(0.1, 0), (1.3, 3), (2.4, 7), (3.5, 1), (4.6, 9), (5.7, 4), (0.9, 6)]])
w('line_same.csv', [(1e-300, 0.0, 0.0), (0.0, 0.0, 0.0), (0.0, 1e-300, 0.0)])
# huge but allowed coordinates: a 1 mm radius circle at 1e11 mm (below the 1e12 mm limit)
w('far_circle.csv', [(1e11 + math.cos(a), 1e11 + math.sin(a), 0.0) for a in [i * 0.6 for i in range(10)]])
w('far_sphere.csv', [(9e11 + 5 * math.cos(a) * math.cos(b), 5 * math.sin(a) * math.cos(b), 5 * math.sin(b)) for a in [i * 0.9 for i in range(7)] for b in (-0.5, 0.3, 1.0)])
w('far_plane.csv', [(9.9e11 + x, 9.9e11 + y, 1e-3 * x) for x in range(4) for y in range(4)])
w('at_limit.csv', [(1e12, 0.0, 0.0), (0.0, 1e12, 0.0), (-1e12, 0.0, 0.0), (0.0, -1e12, 0.0), (0.0, 0.0, 1e12)])
# tiny: a sphere of radius 1e-9 mm, a circle of radius 1e-7 mm at 1000 mm, a plane with 1e-15 scatter
w('tiny_sphere.csv', [(1e-9 * math.cos(a) * math.cos(b), 1e-9 * math.sin(a) * math.cos(b), 1e-9 * math.sin(b)) for a in [i * 0.9 for i in range(7)] for b in (-0.5, 0.3, 1.0)])
w('tiny_circle.csv', [(1000 + 1e-7 * math.cos(a), 1000 + 1e-7 * math.sin(a), 0.0) for a in [i * 0.6 for i in range(10)]])
w('subnormal.csv', [(5e-324 * i, 5e-324 * (i % 3), 0.0) for i in range(8)])
w('circle_arc1deg.csv', [(50 * math.cos(a), 50 * math.sin(a), 0.0) for a in [i * 0.0017 for i in range(10)]])
w('plane_huge_offset_noise.csv', [(x, y, 1e-13 * random.random()) for x in range(5) for y in range(5)])
open('underflow.csv', 'w').write('x_mm,y_mm,z_mm\n1e-400,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0,0,1\n')
open('hexfloat.csv', 'w').write('x_mm,y_mm,z_mm\n0x1p3,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0,0,1\n')
open('spaces.csv', 'w').write('x_mm,y_mm,z_mm\n 1 ,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0,0,1\n')
open('ds_lie.ds', 'w').write('10\n1 0 0\n0 1 0\n-1 0 0\n0 -1 0\n0 0 1\n')
open('ds_huge.ds', 'w').write('18446744073709551615\n1 0 0\n0 1 0\n-1 0 0\n0 -1 0\n0 0 1\n')
PY
run fit "fit line 1 point" "$T" fit line p1.csv
run fit "fit line 2 points (exact)" "$T" fit line p2.csv --json
run fit "fit plane 3 points (exact, --form-tolerance)" "$T" fit plane plane3.csv --json --form-tolerance-mm 0.001
run fit "fit circle 3 points exact, guarded" "$T" fit circle circle3.csv --json --nominal-diameter-mm 10 --tolerance-mm 0.01 --decision-rule guarded
run fit "fit circle 2 points" "$T" fit circle p2.csv
run fit "fit sphere 4 points exact, guarded" "$T" fit sphere sphere4.csv --json --nominal-diameter-mm 10 --tolerance-mm 0.01 --decision-rule guarded
run fit "fit sphere 3 points" "$T" fit sphere sphere3.csv
run fit "fit sphere coplanar 12 points" "$T" fit sphere sphere_coplanar.csv
run fit "fit sphere 0.06 deg cap" "$T" fit sphere sphere_cap.csv --json
run fit "fit cylinder one ring (axis not determined)" "$T" fit cylinder cyl_ring.csv --json
run fit "fit cylinder collinear" "$T" fit cylinder cyl_line.csv
run fit "fit cylinder 6 exact points" "$T" fit cylinder cyl6.csv --json
run fit "fit cylinder 6 exact, minimum-zone" "$T" fit cylinder cyl6.csv --method minimum-zone
run fit "fit cone from cylinder data" "$T" fit cone cone_cyl.csv
run fit "fit cone two rings" "$T" fit cone cone_2rings.csv --json
run fit "fit cone 7 exact points" "$T" fit cone cone7.csv --json
run fit "fit cone 6 points" "$T" fit cone cyl6.csv
run fit "fit line 1e-300 apart" "$T" fit line line_same.csv --json
run fit "fit circle r 1 mm at 1e11 mm" "$T" fit circle far_circle.csv --json
run fit "fit sphere r 5 mm at 9e11 mm" "$T" fit sphere far_sphere.csv --json
run fit "fit plane at 9.9e11 mm" "$T" fit plane far_plane.csv --json
run fit "fit sphere at exactly 1e12 mm" "$T" fit sphere at_limit.csv --json
run fit "fit sphere r 1e-9 mm" "$T" fit sphere tiny_sphere.csv --json
run fit "fit circle r 1e-7 mm at 1000 mm" "$T" fit circle tiny_circle.csv --json
run fit "fit plane subnormal coordinates" "$T" fit plane subnormal.csv --json
run fit "fit circle 0.9 deg arc" "$T" fit circle circle_arc1deg.csv --json
run fit "fit circle 0.9 deg arc --method mic" "$T" fit circle circle_arc1deg.csv --method mic
run fit "fit plane 1e-13 scatter" "$T" fit plane plane_huge_offset_noise.csv --json
run fit "fit sphere 4 exact --method mcc" "$T" fit sphere sphere4.csv --method mcc --json
run fit "fit sphere 4 exact --method minimum-zone" "$T" fit sphere sphere4.csv --method minimum-zone --json
run fit "fit circle 3 exact --method mic" "$T" fit circle circle3.csv --method mic --json
run fit "fit sphere value 1e-400 (underflow)" "$T" fit sphere underflow.csv
run fit "fit sphere hex float 0x1p3" "$T" fit sphere hexfloat.csv
run fit "fit sphere value ' 1 ' with spaces" "$T" fit sphere spaces.csv
run fit "fit sphere .ds count 10, 5 rows" "$T" fit sphere ds_lie.ds
run fit "fit sphere .ds count 2^64-1" "$T" fit sphere ds_huge.ds
run fit "align 3 collinear" bash -c "printf 'id,x_mm,y_mm,z_mm\nA,0,0,0\nB,1,0,0\nC,2,0,0\n' > col3.csv; exec '$T' align --from col3.csv --to col3.csv"
run fit "align --method three-point, 3rd collinear" bash -c "printf 'id,x_mm,y_mm,z_mm\nA,0,0,0\nB,1,0,0\nC,2,0,0\nD,0,1,0\n' > col4.csv; exec '$T' align --from col4.csv --to col4.csv --method three-point"
run fit "autoscale --scale reference at 1e11 spacing 1 mm" bash -c "printf 'id,x_mm,y_mm,z_mm\nA,1e11,0,0\nB,100000000001,0,0\n' > fs.csv; exec '$T' autoscale --reference fs.csv --measured fs.csv --json"
run fit "head-offset one orientation only" bash -c "printf 'b_deg,c_deg,x_mm,y_mm,z_mm\n0,0,12.5,0,0\n0,0,0,12.5,0\n0,0,-12.5,0,0\n0,0,0,-12.5,0\n0,0,0,0,12.5\n' > ho1.csv; exec '$T' head-offset --points ho1.csv --json"

# ---------------------------------------------------------------- 5. probing that measures nothing
PS=(probe sphere --near=0,0,0 --diameter-mm 25 --points 6)
run probing "probe sphere --feed-mm-min 0" "$T" "${PS[@]}" --feed-mm-min 0
run probing "probe sphere --feed-mm-min=-50" "$T" "${PS[@]}" --feed-mm-min=-50
run probing "probe sphere --feed-mm-min 1e-300" "$T" "${PS[@]}" --feed-mm-min 1e-300 --json
note probing "  feed 1e-300: result" 0 "$(tr -d ' \n' < out.txt | grep -o '"radius_mm":[^,]*' | head -1)"
run probing "probe sphere --feed-mm-min NaN" "$T" "${PS[@]}" --feed-mm-min NaN
run probing "probe sphere --feed-mm-min inf" "$T" "${PS[@]}" --feed-mm-min inf
run probing "probe sphere --clearance-mm 0" "$T" "${PS[@]}" --clearance-mm 0
run probing "probe sphere --clearance-mm=-2" "$T" "${PS[@]}" --clearance-mm=-2
run probing "probe sphere --diameter-mm 0" "$T" probe sphere --near=0,0,0 --diameter-mm 0
run probing "probe sphere --diameter-mm=-25" "$T" probe sphere --near=0,0,0 --diameter-mm=-25
run probing "probe sphere --tip-diameter-mm=-3" "$T" "${PS[@]}" --tip-diameter-mm=-3
run probing "probe sphere --tip-diameter-mm NaN" "$T" "${PS[@]}" --tip-diameter-mm NaN
run probing "probe sphere tip 50 mm on a 25 mm sphere" "$T" "${PS[@]}" --tip-diameter-mm 50 --json
run probing "probe sphere --near=NaN,0,0" "$T" probe sphere --near=NaN,0,0 --diameter-mm 25
run probing "probe sphere --near 1,2 (two values)" "$T" probe sphere --near 1,2 --diameter-mm 25
run probing "probe sphere --controller ippdme://127.0.0.1:1 (closed port)" "$T" "${PS[@]}" --controller ippdme://127.0.0.1:1
run probing "probe sphere --controller linuxcncrsh://127.0.0.1:99999" "$T" "${PS[@]}" --controller linuxcncrsh://127.0.0.1:99999
run probing "probe sphere --controller ftp://x" "$T" "${PS[@]}" --controller ftp://x
run probing "somac inspect --depth-mm=-3" "$T" somac inspect --holes holes.csv --diameter-mm 6 --depth-mm=-3 --db p.sqlite
run probing "somac inspect --depth-mm 1e9" "$T" somac inspect --holes holes.csv --diameter-mm 6 --depth-mm 1e9 --db p.sqlite
run probing "somac inspect --diameter-mm 0" "$T" somac inspect --holes holes.csv --diameter-mm 0 --db p.sqlite
run probing "somac inspect tip 10 mm in a 6 mm hole" "$T" somac inspect --holes holes.csv --diameter-mm 6 --tip-diameter-mm 10 --db p.sqlite
run probing "somac inspect tip 5.9 mm in a 6 mm hole (clearance 0.5)" "$T" somac inspect --holes holes.csv --diameter-mm 6 --tip-diameter-mm 5.9 --db p.sqlite
run probing "somac inspect --clearance-mm 0" "$T" somac inspect --holes holes.csv --diameter-mm 6 --clearance-mm 0 --db p.sqlite
run probing "somac inspect --clearance-mm 10 (beyond the hole radius)" "$T" somac inspect --holes holes.csv --diameter-mm 6 --clearance-mm 10 --db p.sqlite
run probing "somac inspect --safe-height-mm=-100" "$T" somac inspect --holes holes.csv --diameter-mm 6 --safe-height-mm=-100 --db p.sqlite
run probing "somac inspect --tolerance-mm=-1" "$T" somac inspect --holes holes.csv --diameter-mm 6 --tolerance-mm=-1 --db p.sqlite
run probing "somac inspect holes diameter_mm column -6" bash -c "printf 'id,x_mm,y_mm,z_mm,diameter_mm\nA,10,20,0,-6\n' > hneg.csv; exec '$T' somac inspect --holes hneg.csv --db p.sqlite"
run probing "somac inspect hole at 1e300" bash -c "printf 'id,x_mm,y_mm,z_mm\nA,1e300,20,0\n' > hfar.csv; exec '$T' somac inspect --holes hfar.csv --diameter-mm 6 --db p.sqlite"
run probing "somac inspect two holes same id" bash -c "printf 'id,x_mm,y_mm,z_mm\nA,10,20,0\nA,30,20,0\n' > hdup.csv; exec '$T' somac inspect --holes hdup.csv --diameter-mm 6 --db p.sqlite"
run probing "somac inspect 0 holes (header only)" bash -c "printf 'id,x_mm,y_mm,z_mm\n' > h0.csv; exec '$T' somac inspect --holes h0.csv --diameter-mm 6 --db p.sqlite"
run probing "head-offset acquire --feed-mm-min 0" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation 0,0 --feed-mm-min 0 --output ha.csv
run probing "head-offset acquire --nominal-offset-mm 1e300" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation 0,0 --orientation 90,0 --nominal-offset-mm 1e300,0,0 --output ha.csv
run probing "head-offset acquire --orientation 1e9,0" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation 1e9,0 --orientation 0,0 --output ha.csv
note probing "  --orientation 1e9,0: first row written" 0 "$(sed -n 2p ha.csv 2>/dev/null | cut -c1-80)"
run probing "head-offset acquire --orientation NaN,0" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation NaN,0 --output ha.csv
run probing "head-offset acquire --table-center-mm 1e300,0,0" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation 0,0 --orientation 0,90 --table-center-mm 1e300,0,0 --output ha.csv
run probing "head-offset --tilt-deg 90,0" "$T" head-offset --points head.csv --tilt-deg 90,0
run probing "head-offset --sphere-diameter-mm=-25" "$T" head-offset --points head.csv --sphere-diameter-mm=-25
run probing "head-offset apply --offset-mm inf,0,0" "$T" head-offset apply --offset-mm inf,0,0 --points head.csv --output hao.csv
KC=(kinematics calibrate --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --orientation 0,0 --orientation 0,120 --orientation 0,240 --orientation 45,0 --orientation 90,120 --points 6)
run probing "kinematics --feed-mm-min 0" "$T" "${KC[@]}" --feed-mm-min 0
run probing "kinematics --feed-mm-min 1e9" "$T" "${KC[@]}" --feed-mm-min 1e9
run probing "kinematics --turn-distance-mm 0" "$T" "${KC[@]}" --turn-distance-mm 0
run probing "kinematics --turn-distance-mm=-60" "$T" "${KC[@]}" --turn-distance-mm=-60
run probing "kinematics --turn-distance-mm 1e12" "$T" "${KC[@]}" --turn-distance-mm 1e12
run probing "kinematics --orientation 720,0 (B beyond a turn)" "$T" kinematics calibrate --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --orientation 0,0 --orientation 0,120 --orientation 720,0 --orientation 90,120 --points 6
run probing "kinematics all orientations equal" "$T" kinematics calibrate --model xyzbc-trt --near=60,25,15 --diameter-mm 25 --orientation 0,0 --orientation 0,0 --orientation 0,0 --points 6
run probing "latency probe --feeds-mm-min 0,0" "$T" latency probe --near=0,0,0 --diameter-mm 25 --feeds-mm-min 0,0
run probing "latency probe --feeds-mm-min 100,100.0001" "$T" latency probe --near=0,0,0 --diameter-mm 25 --feeds-mm-min 100,100.0001
run probing "latency probe --feeds-mm-min 3000,1e9" "$T" latency probe --near=0,0,0 --diameter-mm 25 --feeds-mm-min 3000,1e9
run probing "latency probe --feeds-mm-min NaN,100" "$T" latency probe --near=0,0,0 --diameter-mm 25 --feeds-mm-min NaN,100
run probing "probe sphere --monte-carlo-runs 0" bash -c "printf '[iso10360]\nmpe_e_um = [2, 300]\nmpe_p_um = 2\n' > mm.toml; exec '$T' ${PS[*]} --machine-model mm.toml --monte-carlo-runs 0"
run probing "probe sphere machine-model mpe_p_um = -2" bash -c "printf '[iso10360]\nmpe_e_um = [2, 300]\nmpe_p_um = -2\n' > mmn.toml; exec '$T' ${PS[*]} --machine-model mmn.toml"
run probing "probe sphere machine-model mpe_e_um = [2, 0]" bash -c "printf '[iso10360]\nmpe_e_um = [2, 0]\nmpe_p_um = 2\n' > mm0.toml; exec '$T' ${PS[*]} --machine-model mm0.toml"
run probing "probe sphere machine-model servo_period_ms = 0" bash -c "printf '[machine_tool]\nservo_period_ms = 0\n' > mms.toml; exec '$T' ${PS[*]} --machine-model mms.toml --json"
run probing "latency apply --delay-s 1e300" "$T" latency apply --delay-s 1e300 --machine slat/machine.csv --probe slat/probe.csv --output la.csv
run probing "latency --threshold-mm 0" "$T" latency --machine slat/machine.csv --probe slat/probe.csv --threshold-mm 0
run probing "latency --tip-radius-mm=-2" "$T" latency --machine slat/machine.csv --probe slat/probe.csv --sphere-diameter-mm 25 --tip-radius-mm=-2

# ---------------------------------------------------------------- 6. QIF plans misread
for v in 1 0 ' true ' TRUE 'true false' '\&#116;rue'; do
  qif lim.qif "${DIAM//LIM/$v}$NOM"
  run qif "DefinedAsLimit '$v'" "$T" fit circle c.csv --qif-plan lim.qif --json
  note qif "  DefinedAsLimit '$v' tolerance read" 0 "$(tr -d ' \n' < out.txt | grep -o '"[a-z]*_deviation_mm":[^,]*' | tr '\n' ' ' | cut -c1-110)"
done
qif q.qif "${DIAM//LIM/false}${DIAM//LIM/false}$NOM"; run qif "two definitions with the same id" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}${NOM//Id>2</Id>9<}"; run qif "nominal refers to a missing definition (id 9)" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}${NOM//>2<\/TargetValue/>NaN</TargetValue}"; run qif "TargetValue NaN" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}${NOM//>2<\/TargetValue/>-2</TargetValue}"; run qif "TargetValue -2 (negative diameter)" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}${NOM//>2<\/TargetValue/>1e400</TargetValue}"; run qif "TargetValue 1e400" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}${NOM//>2<\/TargetValue/> 2 </TargetValue}"; run qif "TargetValue ' 2 ' (xsd whitespace)" "$T" fit circle c.csv --qif-plan q.qif --json
qif q.qif "$(printf '%s' "${DIAM//LIM/false}" | sed 's/<MaxValue>0.006/<MaxValue>-0.01/')$NOM"; run qif "MaxValue < MinValue" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "$(printf '%s' "${DIAM//LIM/true}" | sed 's/<MaxValue>0.006/<MaxValue>2.006/; s/<MinValue>-0.001/<MinValue>1.999/')"; run qif "limits without a nominal (DefinedAsLimit true)" "$T" fit circle c.csv --qif-plan q.qif --json
qif q.qif "$(printf '%s' "${DIAM//LIM/false}" | sed 's/<MinValue>-0.001<\/MinValue>//')$NOM"; run qif "MinValue missing" "$T" fit circle c.csv --qif-plan q.qif --json
qif q.qif '<CharacteristicDefinitions n="2"><CircularityCharacteristicDefinition id="5"><ToleranceValue>0.004</ToleranceValue></CircularityCharacteristicDefinition><CircularityCharacteristicDefinition id="6"><ToleranceValue>0.4</ToleranceValue></CircularityCharacteristicDefinition></CharacteristicDefinitions>'
run qif "two circularity definitions" "$T" fit circle c.csv --qif-plan q.qif --json
qif q.qif '<CharacteristicDefinitions n="1"><CircularityCharacteristicDefinition id="5"><ToleranceValue>-0.004</ToleranceValue></CircularityCharacteristicDefinition></CharacteristicDefinitions>'
run qif "circularity ToleranceValue negative" "$T" fit circle c.csv --qif-plan q.qif --json
qif q.qif "${DIAM//LIM/false}$NOM" 'http://qifstandards.org/xsd/qif3' '<FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>in</UnitName><UnitConversion><Factor>0.0254</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>'
run qif "inch plan (Factor 0.0254)" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  inch plan nominal read" 0 "$(tr -d ' \n' < out.txt | grep -o '"nominal_mm":[^,]*' | head -1)"
qif q.qif "${DIAM//LIM/false}$NOM" 'http://qifstandards.org/xsd/qif3' '<FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>furlong</UnitName><UnitConversion><Factor>0</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>'
run qif "unit Factor 0 (furlong)" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}$NOM" 'http://qifstandards.org/xsd/qif3' '<FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>cm</UnitName></LinearUnit></PrimaryUnits></FileUnits>'
run qif "UnitName cm without conversion" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  cm plan nominal read" 0 "$(tr -d ' \n' < out.txt | grep -o '"nominal_mm":[^,]*' | head -1)"
qif q.qif "${DIAM//LIM/false}$NOM" 'http://qifstandards.org/xsd/qif3' ' '
run qif "no FileUnits" "$T" fit circle c.csv --qif-plan q.qif --json
qif q.qif "${DIAM//LIM/false}$NOM" 'http://qifstandards.org/xsd/qif3' '<FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>mm</UnitName><UnitConversion><Factor>0.001</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits><FileUnits><PrimaryUnits><LinearUnit><SIUnitName>meter</SIUnitName><UnitName>in</UnitName><UnitConversion><Factor>0.0254</Factor></UnitConversion></LinearUnit></PrimaryUnits></FileUnits>'
run qif "two FileUnits (mm, then inch)" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  two FileUnits: nominal used" 0 "$(tr -d ' \n' < out.txt | grep -o '"nominal_mm":[^,]*' | head -1)"
qif q.qif "${DIAM//LIM/false}$NOM" 'http://qifstandards.org/xsd/qif3.1'; run qif "namespace qif3.1 (not QIF 3)" "$T" fit circle c.csv --qif-plan q.qif
qif q.qif "${DIAM//LIM/false}$NOM" ''; run qif "no namespace" "$T" fit circle c.csv --qif-plan q.qif
printf '<?xml version="1.0"?>\n<q:QIFDocument xmlns:q="http://qifstandards.org/xsd/qif3"><q:FileUnits><q:PrimaryUnits><q:LinearUnit><q:SIUnitName>meter</q:SIUnitName><q:UnitName>mm</q:UnitName></q:LinearUnit></q:PrimaryUnits></q:FileUnits><q:Characteristics>%s</q:Characteristics></q:QIFDocument>\n' "$(printf '%s' "${DIAM//LIM/false}$NOM" | sed 's/<\([A-Za-z]\)/<q:\1/g; s/<\/\([A-Za-z]\)/<\/q:\1/g')" > q.qif
run qif "prefixed namespace q:QIFDocument" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  prefixed plan nominal read" 0 "$(tr -d ' \n' < out.txt | grep -o '"nominal_mm":[^,]*' | head -1)"
printf '<?xml version="1.0"?>\n<QIFDocument xmlns="http://qifstandards.org/xsd/qif3"><Product><Characteristics>%s</Characteristics></Product><Characteristics>%s</Characteristics></QIFDocument>\n' "${DIAM//LIM/false}${NOM//Value>2</Value>7<}" "${DIAM//LIM/false}$NOM" > q.qif
run qif "a Characteristics (nominal 7) nested in Product, then the top-level one (nominal 2)" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  nested Characteristics: nominal used" 0 "$(tr -d ' \n' < out.txt | grep -o '"nominal_mm":[^,]*' | head -1)"
WIDE="${DIAM//LIM/false}"; WIDE="${WIDE//0.006/0.5}"; WIDE="${WIDE//-0.001/-0.5}"
qif q.qif "${DIAM//LIM/false}${WIDE}$NOM"; run qif "two CharacteristicDefinitions blocks, same id 2, tolerances differ" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  two definition blocks: tolerance used" 0 "$(tr -d ' \n' < out.txt | grep -o '"upper_deviation_mm":[^,]*' | head -1)"
qif q.qif "${DIAM//LIM/false}$NOM${NOM//Value>2</Value>7<}"; run qif "two CharacteristicNominals blocks (nominal 2 and 7)" "$T" fit circle c.csv --qif-plan q.qif --json
note qif "  two nominal blocks: nominal used" 0 "$(tr -d ' \n' < out.txt | grep -o '"nominal_mm":[^,]*' | head -1)"
printf '\xef\xbb\xbf' > bom.qif; cat good.qif >> bom.qif; run qif "UTF-8 BOM" "$T" fit circle c.csv --qif-plan bom.qif --json
iconv -f utf-8 -t utf-16 good.qif > u16.qif 2>/dev/null; run qif "UTF-16 plan" "$T" fit circle c.csv --qif-plan u16.qif
qif q.qif "${DIAM//LIM/false}$NOM"; sed -i 's/<QIFDocument /<QIFDocument idMax="x" /' q.qif; run qif "diameter plan on fit plane (not applicable)" "$T" fit plane c.csv --qif-plan q.qif

# ---------------------------------------------------------------- 7. outputs that destroy what they replace
printf 'keep me\n' > victim.txt; cp victim.txt victim.orig
printf '[ippdme]\nvolume_min_mm = [-500, -500, -500]\nvolume_max_mm = [500, 500, 500]\n' > cmm.toml; cp cmm.toml cmm.orig
mkdir -p outdir; rm -f ofifo; mkfifo ofifo
ln -sf victim.txt olink
ln -f c.csv c_hard.csv 2>/dev/null || cp c.csv c_hard.csv
cp c.csv c.orig; cp map.csv map.orig; cp prog.nc prog.orig; cp tref.csv tref.orig; cp prog.dms prog.dms.orig; cp part.toml part.orig
cp slat/machine.csv lat_m.orig; cp head.csv head.orig; cp sload/points.csv lpts.orig; cp sload/bed.toml bed.orig
outs() { # label, option-taking command prefix...: the output path is appended by each call
  local label=$1; shift
  run outputs "$label -> symlink to another file" "$@" olink; still outputs "  $label: olink" olink symlink; same outputs "  $label: symlink target" victim.txt victim.orig
  run outputs "$label -> FIFO" "$@" ofifo; still outputs "  $label: ofifo" ofifo fifo
  run outputs "$label -> directory" "$@" outdir; still outputs "  $label: outdir" outdir dir
  run outputs "$label -> /dev/full" "$@" /dev/full; still outputs "  $label: /dev/full" /dev/full chardev
}
outs "fit --qif" "$T" fit circle c.csv --qif
outs "latency apply --output" "$T" latency apply --delay-s 0.001 --machine slat/machine.csv --probe slat/probe.csv --output
outs "head-offset apply --output" "$T" head-offset apply --offset-mm 0,0,-100 --points head.csv --output
outs "comp correct --output" "$T" comp correct --map map.csv --points c.csv --output
outs "comp error --output" "$T" comp error --map map.csv --at c.csv --output
outs "load map --output" "$T" load map --bed sload/bed.toml --output
outs "load correct --output" "$T" load correct --map lmap.csv --load sload/load.toml --bed sload/bed.toml --points sload/points.csv --output
outs "scan plan --output" "$T" scan plan --features sscan/features.toml --output
outs "orient --output" "$T" orient --reference tref.csv --measured tmeas.csv --program prog.nc --output
outs "dmis run --output" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output
outs "dmis run --qif" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output dres.dms --qif
outs "head-offset acquire --output" "$T" head-offset acquire --near=0,0,0 --diameter-mm 25 --orientation 0,0 --output
outs "somac inspect --db" "$T" somac inspect --holes holes.csv --diameter-mm 6 --db
# an output that is one of the command's own inputs (not the one named first)
run outputs "comp correct --output = --map" "$T" comp correct --map map.csv --points c.csv --output map.csv; same outputs "  map.csv" map.csv map.orig
run outputs "comp correct --output = --points via hard link" "$T" comp correct --map map.csv --points c.csv --output c_hard.csv; same outputs "  c.csv" c.csv c.orig
run outputs "latency apply --output = --machine" "$T" latency apply --delay-s 0.001 --machine slat/machine.csv --probe slat/probe.csv --output slat/machine.csv; same outputs "  slat/machine.csv" slat/machine.csv lat_m.orig
run outputs "head-offset apply --output = --points (./ path)" "$T" head-offset apply --offset-mm 0,0,-100 --points head.csv --output ./head.csv; same outputs "  head.csv" head.csv head.orig
run outputs "orient --output = --reference" "$T" orient --reference tref.csv --measured tmeas.csv --program prog.nc --output tref.csv; same outputs "  tref.csv" tref.csv tref.orig
run outputs "orient --output = --program via symlinked dir" bash -c "ln -sfn . selfdir; exec '$T' orient --reference tref.csv --measured tmeas.csv --program prog.nc --output selfdir/prog.nc"; same outputs "  prog.nc" prog.nc prog.orig
run outputs "load correct --output = --bed" "$T" load correct --map lmap.csv --load sload/load.toml --bed sload/bed.toml --points sload/points.csv --output sload/bed.toml; same outputs "  bed.toml" sload/bed.toml bed.orig
run outputs "load correct --output = --points" "$T" load correct --map lmap.csv --load sload/load.toml --bed sload/bed.toml --points sload/points.csv --output sload/points.csv; same outputs "  points.csv" sload/points.csv lpts.orig
run outputs "dmis run --output = program" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output prog.dms; same outputs "  prog.dms" prog.dms prog.dms.orig
run outputs "dmis run --qif = program" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output dres.dms --qif prog.dms; same outputs "  prog.dms" prog.dms prog.dms.orig
run outputs "dmis run --qif = --part" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output dres.dms --qif part.toml; same outputs "  part.toml" part.toml part.orig
run outputs "dmis run --output = --machine" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --machine cmm.toml --db o1.sqlite --output cmm.toml; same outputs "  cmm.toml" cmm.toml cmm.orig
run outputs "dmis run --output = --part" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output part.toml; same outputs "  part.toml" part.toml part.orig
run outputs "dmis run --qif = --output (same new file)" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db o1.sqlite --output both.out --qif both.out; note outputs "  both.out after" 0 "$(kind both.out): $(head -c 40 both.out 2>/dev/null | tr '\n' ' ')"
run outputs "dmis run --db = program" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db prog.dms --output dres2.dms; same outputs "  prog.dms" prog.dms prog.dms.orig
run outputs "dmis run --db = --part" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --part part.toml --db part.toml --output dres2.dms; same outputs "  part.toml" part.toml part.orig
run outputs "somac inspect --db = --holes" bash -c "cp holes.csv holes.orig; exec '$T' somac inspect --holes holes.csv --diameter-mm 6 --db holes.csv"; same outputs "  holes.csv" holes.csv holes.orig
run outputs "fit --qif = --qif-plan" bash -c "cp good.qif plan.qif; exec '$T' fit circle c.csv --qif-plan plan.qif --qif plan.qif"; same outputs "  plan.qif" plan.qif good.qif
run outputs "kinematics --output = --machine-model" bash -c "printf '[iso10360]\nmpe_e_um = [2, 300]\nmpe_p_um = 2\n' > km.toml; cp km.toml km.orig; exec '$T' ${KC[*]} --machine-model km.toml --monte-carlo-runs 200 --output km.toml"; same outputs "  km.toml" km.toml km.orig
run outputs "scan run --output = --features" bash -c "cp sscan/features.toml sf.orig; exec '$T' scan run --features sscan/features.toml --output sscan/features.toml"; same outputs "  features.toml" sscan/features.toml sf.orig
run outputs "scan plan --output = --features via hard link" bash -c "ln -f sscan/features.toml sfh.toml; exec '$T' scan plan --features sscan/features.toml --output sfh.toml"; same outputs "  features.toml" sscan/features.toml sf.orig
run outputs "simulate scan --out = a regular file" bash -c "cp victim.orig vfile; exec '$T' simulate scan --out vfile"; same outputs "  vfile" vfile victim.orig
run outputs "simulate comp --out = existing data dir (overwrite?)" bash -c "mkdir -p simd; printf 'mine\n' > simd/map.csv; exec '$T' simulate comp --out simd"; note outputs "  simd/map.csv after" 0 "$(head -c 40 simd/map.csv | tr '\n' ' ')"
# ippdme serve --log: onto its --machine file, a symlink, a FIFO, a directory
TO=3 run outputs "ippdme serve --log = --machine (hard link)" bash -c "ln -f cmm.toml cmmh.toml; exec '$T' ippdme serve --port 0 --machine cmm.toml --log cmmh.toml"; same outputs "  cmm.toml" cmm.toml cmm.orig
TO=3 run outputs "ippdme serve --log symlink" "$T" ippdme serve --port 0 --log olink; same outputs "  victim.txt" victim.txt victim.orig
TO=3 run outputs "ippdme serve --log FIFO" "$T" ippdme serve --port 0 --log ofifo
TO=3 run outputs "ippdme serve --log directory" "$T" ippdme serve --port 0 --log outdir
TO=3 run outputs "ippdme serve --log = --part via symlink" bash -c "ln -sf part.toml partlink.toml; exec '$T' ippdme serve --port 0 --part part.toml --log partlink.toml"; same outputs "  part.toml" part.toml part.orig

# ---------------------------------------------------------------- 8. the I++ DME server's state
cat > ipp.py <<'PY'
import socket, sys, time, re, os
port, pid, mode = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
def hwm():
    try:
        return re.search(r'VmHWM:\s*(\d+)', open(f'/proc/{pid}/status').read()).group(1)
    except Exception:
        return ''
def alive():
    return os.path.exists(f'/proc/{pid}') and 'zombie' not in open(f'/proc/{pid}/status').read()
class C:
    def __init__(s, rcvbuf=None):
        s.s = socket.socket()
        if rcvbuf: s.s.setsockopt(socket.SOL_SOCKET, socket.SO_RCVBUF, rcvbuf)
        s.s.settimeout(15); s.s.connect(('127.0.0.1', port)); s.buf = b''; s.tag = 100
    def lines_until(s, tag, limit=15):
        out, end = [], time.time() + limit
        while time.time() < end:
            while b'\n' in s.buf:
                l, s.buf = s.buf.split(b'\n', 1); l = l.rstrip(b'\r').decode('latin-1'); out.append(l)
                if l.startswith(tag + ' %') or (l.startswith('E0000') and tag == 'E0000'): return out, True
            try:
                d = s.s.recv(1 << 20)
            except socket.timeout:
                break
            except OSError:
                return out, False
            if not d: return out, False
            s.buf += d
        return out, False
    def cmd(s, text, limit=15):
        s.tag += 1; t = '%05d' % s.tag
        s.s.sendall(f'{t} {text}\r\n'.encode('latin-1'))
        return s.lines_until(t, limit)
def summary(lines):
    e = [l for l in lines if ' ! ' in l]
    if e: return e[0][6:][:110]
    d = [l for l in lines if ' # ' in l]
    return (f'{len(d)} data lines; first: ' + (d[0][8:][:70] if d else '-')) if d else ' '.join(lines)[:110]
def row(case, rc, msg, t0):
    print(f'ippdme\t{case}\t{rc}\t{msg}\t{time.time() - t0:.2f}\t{hwm()}', flush=True)
def connection_cases():
    # a client that stops reading: big scan answers never read; the next client must be served
    slow = C(rcvbuf=4096)
    for x in ('StartSession()', 'Home()', 'ChangeTool("Probe1")', 'GoTo(X(50), Y(50), Z(100))'): slow.cmd(x)
    t0 = time.time()
    for i in range(20): slow.s.sendall(b'%05d ScanOnCircle(50, 50, 40, 75, 50, 40, 0, 0, 1, 360, 180, 0.001)\r\n' % (500 + i))
    served, tries = None, 0
    while time.time() - t0 < 19:
        tries += 1
        try:
            n = C(); l, ok = n.cmd('GetDMEVersion()', 3); n.s.close()
            if ok and any('DMEVersion' in x for x in l): served = time.time() - t0; break
        except Exception:
            pass
        time.sleep(0.25)
    row('client stops reading (20 unread 360000-point scans), --write-timeout-s 2: next client', 0 if served and served < 8 else 1,
        f'next client served after {served:.1f} s ({tries} tries)' if served else 'next client NOT served within 19 s', t0)
    try: slow.s.close()
    except Exception: pass
    time.sleep(0.5)
    # an idle client keeps its session beyond the write timeout, the next is refused meanwhile
    t0 = time.time(); idle = C(); idle.cmd('StartSession()'); time.sleep(5)
    try:
        b = C(); l, ok = b.lines_until('E0000', 3); refused = any('0008' in x for x in l); b.s.close()
    except Exception as e:
        refused = False
    l, ok = idle.cmd('Get(X(), Y(), Z())')
    row('idle client 5 s (> write timeout): kept; second refused with 0008', 0 if ok and refused else 1, f'idle answered: {ok}; second refused 0008: {refused}', t0)
    idle.cmd('EndSession()'); idle.s.close()
if mode == 'conn':
    connection_cases(); sys.exit(0)
c = C()
for x in ('StartSession()', 'Home()', 'ChangeTool("Probe1")'): c.cmd(x)
def pos():
    l, ok = c.cmd('Get(X(), Y(), Z())'); d = [x for x in l if ' # ' in x]; return d[0][8:] if d else '?'
def case(name, text, state=True, limit=15):
    global c
    t0 = time.time(); before = pos() if state else ''
    l, ok = c.cmd(text, limit)
    m = summary(l)
    if state and ok:
        c.cmd('ClearAllErrors()'); after = pos(); m = (m + (' | position unchanged' if after == before else f' | POSITION {before} -> {after}'))[:120]
    row(name, 0 if ok else 1, m, t0)
    if not ok:
        try: c = C(); c.cmd('ClearAllErrors()')
        except Exception as e: row(name + ' (reconnect)', 1, repr(e)[:100], t0)
    else:
        c.cmd('ClearAllErrors()')
c.cmd('GoTo(X(50), Y(50), Z(100))')
bore = 'ScanOnCircle(50, 50, 40, 75, 50, 40, 0, 0, 1, %s, 180, %s)'
case('ScanOnCircle delta 721', bore % (721, 1))
case('ScanOnCircle delta -720.5', bore % (-720.5, 1))
case('ScanOnCircle delta 1e300', bore % ('1e300', 1))
case('ScanOnCircle delta NaN', bore % ('NaN', 1))
case('ScanOnCircle delta inf', bore % ('inf', 1))
case('ScanOnCircle StepW -1', bore % (360, -1))
case('ScanOnCircle StepW 1e-300', bore % (360, '1e-300'))
case('ScanOnCircle StepW 0.0003600004 (just under 1e6 points)', bore % (360, '0.0003600004'), limit=60)
case('ScanOnCircle 720 deg StepW 0.001 (720000 points)', bore % (720, '0.001'), limit=60)
case('ScanOnCircle normal 0,0,0', 'ScanOnCircle(50, 50, 40, 75, 50, 40, 0, 0, 0, 90, 180, 1)')
case('ScanOnCircle start = centre (radius 0)', 'ScanOnCircle(50, 50, 40, 50, 50, 40, 0, 0, 1, 90, 180, 1)')
case('ScanOnCircle radius 1e12 mm', 'ScanOnCircle(50, 50, 40, 1000000000050, 50, 40, 0, 0, 1, 1, 180, 0.1)')
case('ScanOnLine 1e300 long', 'ScanOnLine(0, 0, 50, 1e300, 0, 50, 0, 0, 1, 1)')
case('ScanOnLine StepW 1e-300', 'ScanOnLine(60, 60, 50, 70, 60, 50, 0, 0, 1, 1e-300)')
case('ScanOnLine start = end', 'ScanOnLine(60, 60, 50, 60, 60, 50, 0, 0, 1, 1)')
case('AlignPart 1e300 components', 'AlignPart(1e300, 0, 0, 0, 1e300, 0, 0)')
case('AlignPart zero vector', 'AlignPart(0, 0, 0, 0, 0, 1, 0)')
case('AlignPart NaN', 'AlignPart(NaN, 0, 0, 0, 0, 1, 0)')
case('AlignPart 1e-300 components', 'AlignPart(1e-300, 0, 0, 0, 1e-300, 0, 0)')
case('CenterPart 1e300', 'CenterPart(1e300, 0, 0, 0.1)')
case('CenterPart limit -1', 'CenterPart(1, 0, 0, -1)')
case('TiltPart zero direction', 'TiltPart(0, 0, 0, 0.1)')
case('TiltPart 1e300,1e300,1e300', 'TiltPart(1e300, 1e300, 1e300, 0.1)')
case('TiltCenterPart first = second', 'TiltCenterPart(1, 2, 3, 1, 2, 3, 0.001)')
case('TiltCenterPart 1e300 apart', 'TiltCenterPart(0, 0, 0, 0, 0, 1e300, 0.001)')
case('SetCsyTransformation PartCsy origin 1e300', 'SetCsyTransformation(PartCsy, 1e300, 0, 0, 0, 0, 0)')
case('SetCsyTransformation PartCsy angle 1e300 deg', 'SetCsyTransformation(PartCsy, 0, 0, 0, 1e300, 0, 0)')
case('SetCsyTransformation NaN', 'SetCsyTransformation(PartCsy, NaN, 0, 0, 0, 0, 0)')
case('SetCsyTransformation 17-digit number', 'SetCsyTransformation(PartCsy, 12345678901234567, 0, 0, 0, 0, 0)')
case('SetCsyTransformation 1e15 (16 digits, finite)', 'SetCsyTransformation(PartCsy, 1e15, 0, 0, 0, 0, 0)')
l, ok = c.cmd('SetCoordSystem(PartCsy)')
case('PtMeas in a PartCsy at 1e15 mm', 'PtMeas(X(50), Y(50), Z(50), IJK(0, 0, 1))')
c.cmd('SetCsyTransformation(PartCsy, 1e300, 0, 0, 0, 0, 0)')
t0 = time.time(); l, ok = c.cmd('Get(X(), Y(), Z())'); d = [x for x in l if ' # ' in x]
n = max((len(t) for t in re.findall(r'[-0-9.]+', d[0][8:])), default=0) if d else 0
row('Get in a PartCsy whose origin is 1e300 (digits of the longest number)', 0 if n <= 17 else 1, f'longest number {n} characters: {(d[0][8:] if d else summary(l))[:60]}', t0)
c.cmd('SetCsyTransformation(PartCsy, 0, 0, 0, 0, 0, 0)'); c.cmd('SetCoordSystem(MachineCsy)')
case('GoTo X 1e300', 'GoTo(X(1e300))')
case('GoTo X 1e-320 (subnormal)', 'GoTo(X(1e-320), Y(50), Z(100))')
case('PtMeas IJK 0,0,0', 'PtMeas(X(50), Y(50), Z(50), IJK(0, 0, 0))')
case('PtMeas IJK 1e-300,0,0', 'PtMeas(X(60), Y(60), Z(50), IJK(0, 0, 1e-300))')
case('SetProp PtMeasPar.Speed 0', 'SetProp(Tool.PtMeasPar.Speed(0))')
case('SetProp PtMeasPar.Search 1e300', 'SetProp(Tool.PtMeasPar.Search(1e300))')
case('SetProp PtMeasPar.Approach -5', 'SetProp(Tool.PtMeasPar.Approach(-5))')
case('PtMeas after those SetProps', 'PtMeas(X(60), Y(60), Z(50), IJK(0, 0, 1))')
case('SetProp GoToPar.Speed 1e300', 'SetProp(Tool.GoToPar.Speed(1e300))')
case('OnScanReport 10000 fields', 'OnScanReport(' + ', '.join(['X()'] * 10000) + ')', state=False)
# a line without end, beyond 64 KiB
t0 = time.time(); c.s.sendall(b'00901 Get(' + b'X(), ' * 20000); l, ok = c.lines_until('E0000', 10)
row('line of 100 KB without end', 0 if any('Buffer full' in x for x in l) else 1, summary(l), t0)
# non-ASCII and NUL
c = C(); c.cmd('ClearAllErrors()')
t0 = time.time(); c.s.sendall(b'00902 Get(X()\xff\x00)\r\n'); l, ok = c.lines_until('00902', 5); row('bytes 0xFF and NUL in a command', 0 if ok else 1, summary(l), t0)
# a flood of 100000 pipelined commands (answers read)
t0 = time.time(); c.s.sendall(b''.join(b'%05d Get(X(), Y(), Z())\r\n' % (10000 + i) for i in range(80000)))
l, ok = c.lines_until('%05d' % (10000 + 79999), 60); row('80000 pipelined Get (answers read)', 0 if ok else 1, f'{len(l)} lines back', t0)
c.cmd('EndSession()'); c.s.close(); time.sleep(0.5)
t0 = time.time()
row('server still alive after all cases', 0 if alive() else 1, 'alive' if alive() else 'DEAD', t0)
PY
cat > ipart.toml <<'EOF'
[[plane]]
point_mm = [50.0, 50.0, 50.0]
normal = [0.0, 0.0, 1.0]

[[cylinder]]
point_mm = [50.0, 50.0, 0.0]
axis = [0.0, 0.0, 1.0]
diameter_mm = 50.0
side = "inside"
EOF
$PIN prlimit --as=2000000000 -- "$T" ippdme serve --port 0 --part ipart.toml --log srv.log --write-timeout-s 2 2> srv.err &
SRV=$!; BG+=($SRV)
for i in $(seq 50); do grep -q 'listening on' srv.err && break; sleep 0.1; done
PORT=$(grep -o 'listening on [0-9.]*:[0-9]*' srv.err | grep -o '[0-9]*$')
if [ -n "$PORT" ]; then
  $PIN timeout 200 python3 ipp.py "$PORT" "$SRV" state || note ippdme "client script" $? "client script failed"
  note ippdme "server log size after the session" 0 "$(stat -c %s srv.log) bytes; server stderr: $(grep -v listening srv.err | head -1 | cut -c1-60)"
else
  note ippdme "server start" 1 "$(head -1 srv.err)"
fi
kill "$SRV" 2>/dev/null; wait "$SRV" 2>/dev/null
# the connection cases on a fresh server (its part where the scans find the bore)
$PIN prlimit --as=2000000000 -- "$T" ippdme serve --port 0 --part ipart.toml --log srv2.log --write-timeout-s 2 2> srv2.err &
SRV=$!; BG+=($SRV)
for i in $(seq 50); do grep -q 'listening on' srv2.err && break; sleep 0.1; done
PORT=$(grep -o 'listening on [0-9.]*:[0-9]*' srv2.err | grep -o '[0-9]*$')
[ -n "$PORT" ] && { $PIN timeout 100 python3 ipp.py "$PORT" "$SRV" conn || note ippdme "client script (conn)" $? "client script failed"; }
note ippdme "  server log: disconnections" 0 "$(grep -a -c 'write timeout' srv2.log) for a write timeout"
kill "$SRV" 2>/dev/null; wait "$SRV" 2>/dev/null

# ---------------------------------------------------------------- 9. messages (exit 2, file, line/field, limit) and CR-only line ends
printf 'G90\rG0 X1 Y2 Z3\rG1 X10 Y10 Z0 F100\r' > mac.nc
run messages "orient CR-only G-code" "$T" orient --reference tref.csv --measured tmeas.csv --program mac.nc --output o.nc
note messages "  orient CR-only output (LF program gives X2.0000 then X11.0000)" 0 "$(tr '\r' '|' < o.nc | cut -c1-100)"; rm -f o.nc
tr '\n' '\r' < prog.dms > mac.dms; run messages "dmis run CR-only DMIS" "$T" dmis run mac.dms --sensor PROBE6=Probe1 --part part.toml --db m.sqlite --output mo.dms
tr '\n' '\r' < part.toml > macpart.toml; run messages "dmis run --part CR-only TOML" "$T" dmis run prog.dms --part macpart.toml --db m.sqlite --output mo.dms
tr '\n' '\r' < sq.toml > macsq.toml; run messages "comp --squareness CR-only TOML" "$T" comp correct --map map.csv --squareness macsq.toml --points c.csv --output cc.csv
tr '\n' '\r' < sscan/features.toml > macf.toml; run messages "scan plan CR-only features TOML" "$T" scan plan --features macf.toml --output sp.csv
tr '\n' '\r' < sload/bed.toml > macbed.toml; run messages "load map CR-only bed TOML" "$T" load map --bed macbed.toml --output lm.csv
tr '\n' '\r' < ssomac/program.nc > macsomac.nc; run messages "somac inspect CR-only program" "$T" somac inspect --program macsomac.nc --diameter-mm 6 --db m.sqlite --json
note messages "  holes inspected (CR-only / LF program)" 0 "$(grep -c '"hole"\|"id"' out.txt) / $("$T" somac inspect --program ssomac/program.nc --diameter-mm 6 --db m.sqlite --json 2>/dev/null | grep -c '"hole"\|"id"')"
TO=3 run messages "ippdme serve CR-only part TOML" "$T" ippdme serve --port 0 --part macpart.toml
tr '\n' '\r' < map.csv > macmap.csv; run messages "comp correct CR-only --map" "$T" comp correct --map macmap.csv --points c.csv --output cc.csv
printf '5\r1 0 0\r0 1 0\r-1 0 0\r0 -1 0\r0 0 1\r' > mac.ds; run messages "fit sphere CR-only .ds" "$T" fit sphere mac.ds
tr '\n' '\r' < tref.csv > mactref.csv; run messages "align CR-only --from" "$T" align --from mactref.csv --to tmeas.csv
tr '\n' '\r' < head.csv > machead.csv; run messages "head-offset apply CR-only points" "$T" head-offset apply --offset-mm 0,0,-100 --points machead.csv --output hao.csv
printf 'x_mm,y_mm,z_mm\r\n1,0,0\r\n0,1,0\r\n-1,0,0\r\n0,-1,0\r\n0,0,1\r\n' > crlf.csv; run messages "fit sphere CRLF (must work)" "$T" fit sphere crlf.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n0,1\n-1,0,0\n0,-1,0\n0,0,1\n' > ragged.csv; run messages "ragged row" "$T" fit sphere ragged.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n0,1,0,7\n-1,0,0\n0,-1,0\n0,0,1\n' > ragged2.csv; run messages "row with an extra field" "$T" fit sphere ragged2.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n0,1,NaN\n-1,0,0\n0,-1,0\n0,0,1\n' > nan.csv; run messages "NaN value" "$T" fit sphere nan.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n0,1,1,5\n' > q.csv; run messages "comma decimal unquoted" "$T" fit sphere q.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n"0",1,0\n-1,0,0\n0,-1,0\n0,0,1\n' > quoted.csv; run messages "quoted number (must work)" "$T" fit sphere quoted.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n"0,1,0\n-1,0,0\n0,-1,0\n0,0,1\n' > unq.csv; run messages "unterminated quote" "$T" fit sphere unq.csv
printf 'x_mm,x_mm,y_mm,z_mm\n1,9,0,0\n0,9,1,0\n-1,9,0,0\n0,9,-1,0\n0,9,0,1\n' > dupcol.csv; run messages "duplicate column x_mm" "$T" fit sphere dupcol.csv --json
printf '\xef\xbb\xbfx_mm,y_mm,z_mm\n1,0,0\n0,1,0\n-1,0,0\n0,-1,0\n0,0,1\n' > bom.csv; run messages "UTF-8 BOM (must work)" "$T" fit sphere bom.csv
iconv -f utf-8 -t utf-16 crlf.csv > u16.csv 2>/dev/null; run messages "UTF-16 CSV" "$T" fit sphere u16.csv
printf 'x_mm,y_mm,z_mm\n1,0,0\n0,\xff,0\n' > latin.csv; run messages "invalid UTF-8 in a value" "$T" fit sphere latin.csv
: > empty.csv; run messages "empty CSV" "$T" fit sphere empty.csv
printf 'x_mm,y_mm,z_mm\n' > hdr.csv; run messages "header only" "$T" fit sphere hdr.csv
printf '# a\n# b\n' > comments.csv; run messages "comments only" "$T" fit sphere comments.csv
run messages "missing file" "$T" fit sphere nonexistent.csv
run messages "points is a directory" "$T" fit sphere outdir
printf 'x_mm,y_mm,z_mm\n1,0,0\n' > noperm.csv; chmod 000 noperm.csv; run messages "unreadable file (chmod 000; root reads anyway)" "$T" fit sphere noperm.csv; chmod 644 noperm.csv
printf '[squareness]\nxy_urad = "1"\n' > sqs.toml; run messages "TOML value of the wrong type" "$T" comp correct --map map.csv --squareness sqs.toml --points c.csv --output cc.csv
printf '[squareness]\nxy_urad = nan\nxz_urad = 0\nyz_urad = 0\n' > sqn.toml; run messages "TOML nan" "$T" comp correct --map map.csv --squareness sqn.toml --points c.csv --output cc.csv
printf '[squareness]\nxy_urad = 1\nxy_urad = 2\n' > sqd.toml; run messages "TOML duplicate key" "$T" comp correct --map map.csv --squareness sqd.toml --points c.csv --output cc.csv
printf '[squareness]\nxy_urad = 1\nxz_urad = 0\nyz_urad = 0\nzz_urad = 5\n' > squ.toml; run messages "TOML unknown key" "$T" comp correct --map map.csv --squareness squ.toml --points c.csv --output cc.csv
printf 'mass_kg = 1e300\ncog_mm = [1260, 760]\nrest_points_mm = [[850, 450], [1750, 520], [1200, 1180]]\n' > lbig.toml; run messages "load mass 1e300 kg" "$T" load curves --map lmap.csv --load lbig.toml --json
note messages "  load mass 1e300 kg: forces" 0 "$(tr -d ' \n' < out.txt | grep -o '"forces_n":[^]]*' | cut -c1-100)"
printf 'mass_kg = -2000\ncog_mm = [1260, 760]\nrest_points_mm = [[850, 450], [1750, 520], [1200, 1180]]\n' > lneg.toml; run messages "load mass negative" "$T" load curves --map lmap.csv --load lneg.toml --json
printf 'mass_kg = 2000\ncog_mm = [1260, 760]\nrest_points_mm = [[850, 450], [850, 450], [850, 450]]\n' > lsame.toml; run messages "load three identical rest points" "$T" load curves --map lmap.csv --load lsame.toml --json
run messages "air --co2-ppm 2001" "$T" air --temperature-c 20 --pressure-pa 101325 --humidity-pct 50 --co2-ppm 2001
run messages "air --humidity-pct NaN" "$T" air --temperature-c 20 --pressure-pa 101325 --humidity-pct NaN
run messages "air --formula edlen --co2-ppm 400" "$T" air --temperature-c 20 --pressure-pa 101325 --humidity-pct 50 --formula edlen --co2-ppm 400
run messages "orient G-code word 1e309 in expression" bash -c "printf 'G0 X[1e308*10] Y0 Z0\n' > gx.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gx.nc --output o.nc"
run messages "orient G-code divide by zero" bash -c "printf 'G0 X[1/0] Y0 Z0\n' > gd.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gd.nc --output o.nc"
run messages "orient G-code 10000 nested brackets" bash -c "python3 -c \"print('G0 X' + '['*10000 + '1' + ']'*10000 + ' Y0 Z0')\" > gn.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gn.nc --output o.nc"
python3 -c "print('#1=[' + '1+' * 10000 + '1]')" > flat.nc; cat ssomac/program.nc >> flat.nc
run crash "orient G-code expression of 10001 terms (20 KB line)" "$T" orient --reference tref.csv --measured tmeas.csv --program flat.nc --output o.nc
run crash "orient G-code 20000 unary minus" bash -c "python3 -c \"print('G0 X[' + '-' * 20000 + '1] Y0 Z0')\" > um.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program um.nc --output o.nc"
python3 -c "print('#1=[' + '1+' * 200000 + '1]')" > flat2.nc; cat ssomac/program.nc >> flat2.nc
run crash "somac inspect program with a 200001-term expression (400 KB line)" "$T" somac inspect --program flat2.nc --diameter-mm 6 --db fl.sqlite
run crash "somac run program with a 200001-term expression (400 KB line)" "$T" somac run --program flat2.nc --cell ssomac/cell.toml --db fl2.sqlite
run messages "orient G-code 100000 nested comments" bash -c "python3 -c \"print('G0 X1 Y0 Z0 ' + '('*100000 + ')'*100000)\" > gc.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gc.nc --output o.nc"
run messages "orient G-code unclosed comment" bash -c "printf 'G0 X1 Y0 Z0 (open\nG1 X2\n' > gu.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gu.nc --output o.nc"
run messages "orient G-code parameter #99999999" bash -c "printf '#99999999=5\nG0 X#99999999 Y0 Z0\n' > gp.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gp.nc --output o.nc"
run messages "orient G-code undefined parameter #7" bash -c "printf 'G0 X#7 Y0 Z0\n' > gq.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gq.nc --output o.nc"
run messages "orient G20 inch program" bash -c "printf 'G20 G90\nG0 X1 Y2 Z3\n' > gi.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gi.nc --output o.nc --json"
run messages "orient G91 incremental program" bash -c "printf 'G91\nG0 X1 Y2 Z3\nG0 X1\n' > gr.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program gr.nc --output o.nc"
run messages "orient G53 machine coordinates" bash -c "printf 'G90\nG53 G0 X1 Y2 Z3\n' > g53.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program g53.nc --output o.nc"
run messages "orient G68 rotation in program" bash -c "printf 'G90\nG68 X0 Y0 R45\nG0 X1 Y2 Z3\n' > g68.nc; exec '$T' orient --reference tref.csv --measured tmeas.csv --program g68.nc --output o.nc"
rm -f o.nc

# ---------------------------------------------------------------- 10. DMIS programs
dm() { # case, file, [extra options]
  local c=$1 f=$2; shift 2
  run dmis "$c" "$T" dmis run "$f" --sensor PROBE6=Probe1 --part part.toml --db dm.sqlite --output dmo.dms "$@"
}
sed '/ENDFIL/d' prog.dms > d_noend.dms; dm "no ENDFIL" d_noend.dms
sed '/ENDMES/d' prog.dms > d_noendmes.dms; dm "MEAS without ENDMES" d_noendmes.dms
sed 's/^MEAS\/CIRCLE,F(C1),4/MEAS\/CIRCLE,F(C1),4\nMEAS\/CIRCLE,F(C1),4/' prog.dms > d_nested.dms; dm "MEAS nested in MEAS" d_nested.dms
sed 's/^ENDFIL/ENDFIL\nGOTO\/1,2,3/' prog.dms > d_after.dms; dm "statements after ENDFIL" d_after.dms
sed 's/^OUTPUT/CALL\/EXTERN,DMIS,M(X)\nOUTPUT/' prog.dms > d_call.dms; dm "unsupported CALL" d_call.dms
sed 's/^OUTPUT/DO\/I,1,10,1\nENDDO\nOUTPUT/' prog.dms > d_do.dms; dm "unsupported DO loop" d_do.dms
sed 's/^OUTPUT/IF\/(1 .EQ. 1)\nENDIF\nOUTPUT/' prog.dms > d_if.dms; dm "unsupported IF" d_if.dms
sed 's/^MEAS\/CIRCLE,F(C1),4/MEAS\/CIRCLE,F(C1),1000000000/' prog.dms > d_cnt.dms; dm "MEAS count 1e9 with 4 PTMEAS" d_cnt.dms
sed 's/^MEAS\/CIRCLE,F(C1),4/MEAS\/CIRCLE,F(C1),2/' prog.dms > d_cnt2.dms; dm "MEAS count 2 with 4 PTMEAS" d_cnt2.dms
awk '/^PTMEAS/{n++; if(n>2) next} {print}' prog.dms | sed 's/,4$/,2/' > d_two.dms; dm "circle from 2 PTMEAS" d_two.dms
sed 's/^PTMEAS\/CART, 25.0, 50.0, 40.0/PTMEAS\/CART, 75.0, 50.0, 40.0/; s/^PTMEAS\/CART, 50.0, 75.0, 40.0,  0.0, -1.0/PTMEAS\/CART, 75.0, 50.0, 40.0, -1.0,  0.0/; s/^PTMEAS\/CART, 50.0, 25.0, 40.0,  0.0,  1.0/PTMEAS\/CART, 75.0, 50.0, 40.0, -1.0,  0.0/' prog.dms > d_same.dms; dm "circle from 4 PTMEAS at one spot" d_same.dms
sed 's/^FEDRAT.*//; s/^GOTO\/50.0, 50.0, 75.0/FEDRAT\/POSVEL,MPM,1e9\nGOTO\/50.0, 50.0, 75.0/' prog.dms > d_fed.dms; dm "FEDRAT 1e9 m/min" d_fed.dms
sed 's/^GOTO\/50.0, 50.0, 75.0/FEDRAT\/MESVEL,MPM,0\nGOTO\/50.0, 50.0, 75.0/' prog.dms > d_fed0.dms; dm "FEDRAT MESVEL 0" d_fed0.dms
sed 's/^GOTO\/50.0, 50.0, 75.0/SNSET\/APPRCH,1e300\nGOTO\/50.0, 50.0, 75.0/' prog.dms > d_appr.dms; dm "SNSET APPRCH 1e300" d_appr.dms
sed 's/^GOTO\/50.0, 50.0, 75.0/SNSET\/SEARCH,-10\nGOTO\/50.0, 50.0, 75.0/' prog.dms > d_srch.dms; dm "SNSET SEARCH -10" d_srch.dms
sed 's/^GOTO\/50.0, 50.0, 75.0/GOTO\/1e300, 50.0, 75.0/' prog.dms > d_goto.dms; dm "GOTO 1e300" d_goto.dms
sed 's/^GOTO\/50.0, 50.0, 75.0/GOTO\/NaN, 50.0, 75.0/' prog.dms > d_gnan.dms; dm "GOTO NaN" d_gnan.dms
sed 's/4.0$/0.0/' prog.dms > d_tip0.dms; dm "SNSDEF tip diameter 0" d_tip0.dms
sed 's/4.0$/-4.0/' prog.dms > d_tipn.dms; dm "SNSDEF tip diameter -4" d_tipn.dms
sed 's/, 50.0$/, 0.0/' prog.dms > d_d0.dms; dm "FEAT circle diameter 0" d_d0.dms
sed 's/0.0, 0.0, 1.0, 50.0$/0.0, 0.0, 0.0, 50.0/' prog.dms > d_n0.dms; dm "FEAT circle normal 0,0,0" d_n0.dms
sed 's/UNITS\/ MM, ANGDEC/UNITS\/ FURLONG, ANGDEC/' prog.dms > d_units.dms; dm "UNITS FURLONG" d_units.dms
sed 's/UNITS\/ MM, ANGDEC/UNITS\/ INCH, ANGDEC/' prog.dms > d_inch.dms; dm "UNITS INCH (program in mm numbers: far off the part)" d_inch.dms
sed 's/^OUTPUT\/FA(C1)/OUTPUT\/FA(NOPE)/' prog.dms > d_out.dms; dm "OUTPUT of an undefined label" d_out.dms
sed 's/^OUTPUT/T(TOL1)=TOL\/DIAM,-1,1\nOUTPUT/' prog.dms > d_tol.dms; dm "TOL DIAM limits -1,1 (lower > ... fine), no TA" d_tol.dms
sed 's/^OUTPUT/T(TOL1)=TOL\/DIAM,1,-1\nOUTPUT\/FA(C1),TA(TOL1)\nOUTPUT/' prog.dms > d_tolinv.dms; dm "TOL DIAM lower 1 > upper -1" d_tolinv.dms
sed 's/^OUTPUT/T(TOL1)=TOL\/CIRLTY,-0.01\nOUTPUT\/FA(C1),TA(TOL1)\nOUTPUT/' prog.dms > d_tolneg.dms; dm "TOL CIRLTY negative" d_tolneg.dms
sed 's/^F(C1) = /F(C1) = FEAT\/POINT,CART,0,0,0,0,0,1\nF(C1) = /' prog.dms > d_redef.dms; dm "label F(C1) defined twice" d_redef.dms
python3 -c "
l = open('prog.dms').read().replace('F(C1)', 'F(' + 'L' * 100000 + ')'); open('d_longlabel.dms', 'w').write(l)"; dm "label of 100000 characters" d_longlabel.dms
python3 -c "
s = open('prog.dms').read().split('\n'); i = [k for k, x in enumerate(s) if x.startswith('GOTO/50.0, 50.0, 75.0')][0]
s[i] = 'GOTO/50.0,\$\n' + '\$\n' * 200000 + '50.0, 75.0'; open('d_cont.dms', 'w').write('\n'.join(s))"; dm "200000 continuation lines" d_cont.dms
python3 -c "
s = open('prog.dms').read().replace('ENDFIL', 'GOTO/50.0, 50.0, 100.0\n' * 2000000 + 'ENDFIL'); open('d_huge.dms', 'w').write(s)"; dm "2 M GOTO statements (46 MB)" d_huge.dms --dry-run
python3 -c "
s = open('prog.dms').read().replace('ENDFIL', ('\$\$ ' + 'x' * 2000000) + '\nENDFIL'); open('d_longline.dms', 'w').write(s)"; dm "a 2 MB comment line" d_longline.dms
python3 -c "
s = open('prog.dms').read().replace('GOTO/50.0, 50.0, 75.0', 'GOTO/' + '(' * 10000 + '50.0' + ')' * 10000 + ', 50.0, 75.0'); open('d_paren.dms', 'w').write(s)"; dm "10000 nested parentheses in a number" d_paren.dms
python3 -c "
s = open('prog.dms').read().replace('ENDFIL', 'TEXT/OPER,\'' + 'a' * 1000 + '\n' + 'ENDFIL'); open('d_quote.dms', 'w').write(s)"; dm "unterminated string" d_quote.dms
printf 'DMISMN/ '"'"'X'"'"'\n' > d_only.dms; dm "DMISMN only" d_only.dms
: > d_empty.dms; dm "empty program" d_empty.dms
printf 'DMISMN/ '"'"'X'"'"'\nENDFIL\n' > d_min.dms; dm "DMISMN ENDFIL only (nothing to do)" d_min.dms
sed 's/^ENDFIL/DID(D1)=DEVICE\/STOR,'"'"'..\/..\/..\/escaped.dms'"'"'\nOPEN\/DID(D1),DIRECT,OUTPUT,OVERWR\nENDFIL/' prog.dms > d_dev.dms
mkdir -p sub/a/b; cp d_dev.dms sub/a/b/
run dmis "DEVICE names ../../../escaped.dms (no --output)" "$T" dmis run sub/a/b/d_dev.dms --sensor PROBE6=Probe1 --part part.toml --db dm.sqlite
note dmis "  escaped.dms written where" 0 "$(ls escaped.dms sub/escaped.dms 2>/dev/null | tr '\n' ' ')$(ls ../escaped.dms 2>/dev/null)"
sed 's/^ENDFIL/DID(D1)=DEVICE\/STOR,'"'"'d_self.dms'"'"'\nOPEN\/DID(D1),DIRECT,OUTPUT,OVERWR\nENDFIL/' prog.dms > d_self.dms; cp d_self.dms d_self.orig
run dmis "DEVICE names the program itself (no --output)" "$T" dmis run d_self.dms --sensor PROBE6=Probe1 --part part.toml --db dm.sqlite; same dmis "  d_self.dms" d_self.dms d_self.orig
sed 's/^ENDFIL/DID(D1)=DEVICE\/STOR,'"'"'\/dev\/full'"'"'\nOPEN\/DID(D1),DIRECT,OUTPUT,OVERWR\nENDFIL/' prog.dms > d_full.dms; run dmis "DEVICE names /dev/full" "$T" dmis run d_full.dms --sensor PROBE6=Probe1 --part part.toml --db dm.sqlite
sed 's/^ENDFIL/DID(D1)=DEVICE\/STOR,'"'"'olink'"'"'\nOPEN\/DID(D1),DIRECT,OUTPUT,OVERWR\nENDFIL/' prog.dms > d_link.dms; run dmis "DEVICE names a symlink to another file" "$T" dmis run d_link.dms --sensor PROBE6=Probe1 --part part.toml --db dm.sqlite; same dmis "  victim.txt" victim.txt victim.orig; still dmis "  olink" olink symlink
sed 's/^ENDFIL/DID(D1)=DEVICE\/STOR,'"'"'part.toml'"'"'\nOPEN\/DID(D1),DIRECT,OUTPUT,OVERWR\nENDFIL/' prog.dms > d_part.dms; run dmis "DEVICE names the --part file" "$T" dmis run d_part.dms --sensor PROBE6=Probe1 --part part.toml --db dm.sqlite; same dmis "  part.toml" part.toml part.orig
run dmis "--sensor PROBE6=NoSuchTool" "$T" dmis run prog.dms --part part.toml --db dm.sqlite --output dmo.dms --sensor PROBE6=NoSuchTool
run dmis "--sensor PROBE6=NoTool (cannot measure)" "$T" dmis run prog.dms --part part.toml --db dm.sqlite --output dmo.dms --sensor PROBE6=NoTool
run dmis "--controller ippdme://127.0.0.1:1 (nothing listens)" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --db dm.sqlite --output dmo.dms --controller ippdme://127.0.0.1:1
run dmis "no --part (ideal planes)" "$T" dmis run prog.dms --sensor PROBE6=Probe1 --db dm.sqlite --output dmo.dms --json
run dmis "part without the bore (PTMEAS finds nothing)" bash -c "head -4 part.toml > topo.toml; exec '$T' dmis run prog.dms --sensor PROBE6=Probe1 --part topo.toml --db dm.sqlite --output dmo_miss.dms"
note dmis "  output after a failed run" 0 "$(kind dmo_miss.dms)"

# ---------------------------------------------------------------- temp files left behind by any case above
find . -name '.*.tmp-*' -printf '%P\t%s\n' | while IFS=$'\t' read -r f sz; do note outputs "temp file left behind" 1 "$f ($sz bytes)"; done
