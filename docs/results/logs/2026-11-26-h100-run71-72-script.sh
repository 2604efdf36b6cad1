set -u
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z5/*.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
"
B=/tmp/b; S=.dev/scenes; C=scenes/cameras
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); tools at $(cat .dev/commit5)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT/bs; cp -r docs/results/build-sweep-h100/sanmiguel $OUT/bs/
sw(){ L=$1; shift; echo "== build sweep $* (at $(el) s, limit $L s)"; timeout $L python3 tools/as-accuracy --build-sweep --bin $B --out $OUT/bs "$@" 2>&1 | grep -vE "^\[|: (tracing|building)" | tail -3; }
sw $(( 570 - $(el) )) --merge --cap 60 --builders $1 $S/sanmiguel.drc@$C/sanmiguel.cam
grep -c "^| " $OUT/bs/sanmiguel/build-sweep.md; grep -i partial $OUT/bs/sanmiguel/build-sweep.md
cd $OUT && tar czf bs.tar.gz bs && rm -rf bs; date -u; echo "total $(el) s"
