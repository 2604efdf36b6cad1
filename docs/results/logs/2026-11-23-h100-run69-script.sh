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
mkdir -p $OUT/bs; cp -r .dev/bs/chopper-titan $OUT/bs/
sw(){ L=$1; shift; echo "== build sweep $* (at $(el) s, limit $L s)"; timeout $L python3 tools/as-accuracy --build-sweep --bin $B --out $OUT/bs "$@" 2>&1 | grep -vE "^\[|: (tracing|building)" | tail -3; }
sw 300 --merge --builders grid $S/chopper-titan.drc@$C/chopper-titan.cam
cd $OUT && tar czf bs.tar.gz bs && rm -rf bs; cd - >/dev/null
export BIN=$B
rc(){ L=$1 n=$2; shift 2; [ $L -lt 20 ] && { echo "skip $n: time"; return; }; echo "== recompute $n (at $(el) s, limit $L s)"; timeout $L sh scripts/recompute_published.sh /tmp/rc/$n "$@" 2>/tmp/rc-$n.err | tail -2; tail -3 /tmp/rc-$n.err; mkdir -p $OUT/rc/$n; cp /tmp/rc/$n/*.same-rays.json /tmp/rc/$n/*.published.json /tmp/rc/$n/summary.md $OUT/rc/$n/ 2>/dev/null; }
A=docs/results/accuracy-h100
INTERSECTORS="watertight-double" SAMPLES=2000 rc $(( 570 - $(el) )) chopper-titan $S/chopper-titan.drc -3,1.5,-10@2,1,20@0,1,0@60 $A/chopper-titan/accuracy.json "bvh sbvh cwbvh CWBVH (SBVH)"
cd $OUT && tar czf rc.tar.gz rc 2>/dev/null; rm -rf rc; ls -la; date -u; echo "total $(el) s"
