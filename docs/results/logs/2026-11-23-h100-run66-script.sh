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
mkdir -p $OUT/bs; cp -r docs/results/build-sweep-h100/bathroom $OUT/bs/
sw(){ L=$1; shift; echo "== build sweep $* (at $(el) s, limit $L s)"; timeout $L python3 tools/as-accuracy --build-sweep --bin $B --out $OUT/bs "$@" 2>&1 | grep -vE "^\[|: (tracing|building)" | tail -3; }
sw 120 --merge --builders grid $S/bathroom.drc@$C/bathroom.cam
sw $(( 560 - $(el) )) $S/staircase2.ply.zst@$C/staircase2.cam
sw $(( 560 - $(el) )) $S/bathroom2.drc@$C/bathroom2.cam
L=$(( 565 - $(el) )); [ $L -gt 40 ] && sw $L $S/bmw-m6.drc@$C/bmw-m6.cam
cd $OUT && tar czf bs.tar.gz bs && rm -rf bs; date -u; echo "total $(el) s"
