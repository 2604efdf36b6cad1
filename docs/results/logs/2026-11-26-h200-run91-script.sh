set -u
# Run 91: the KD SAH cost that counts a triangle starting or ending in the plane on both sides
# (A: 2983d28 with that change, not committed) against 2983d28 (B): KD-standard and KD-ropes trees
# built on the host (16 threads), traced on the GPU, Whitted and AO, 1920x1080, default camera,
# median of 10 launches; steps and triangle tests per ray of the AO workload on the CPU at 480x270.
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/kd/A',exist_ok=True); os.makedirs('/tmp/kd/B',exist_ok=True)
for f in glob.glob('.dev/kd/*.xz'):
    n=os.path.basename(f)[:-3]
    d={'A.so':'/tmp/kd/A/libas.so.0','B.so':'/tmp/kd/B/libas.so.0'}.get(n,'/tmp/kd/'+n)
    open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
"
export LD_LIBRARY_PATH=$PWD/.dev/lib
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader
for s in staircase.ply.zst bathroom.drc bmw-m6.drc bunny.ply.zst; do for v in B A; do
  LD_LIBRARY_PATH=/tmp/kd/$v:$PWD/.dev/lib /tmp/kd/savest $S/$s kd:sah 16 /tmp/kd/$v.asf || continue
  /tmp/kd/as-convert /tmp/kd/$v.asf -o /tmp/kd/$v-ropes.asf --layout kd-ropes >/dev/null || continue
  for f in $v $v-ropes; do
    echo "== $s $f: $(stat -c %s /tmp/kd/$f.asf) bytes"
    for w in whitted ao; do
      /tmp/kd/as-trace /tmp/kd/$f.asf --device gpu -w $w -W 1920 -H 1080 --runs 10 2>&1 | grep -E "^(primary|whitted total|ao) " | sed "s/^/  gpu $w: /"
    done
    /tmp/kd/as-trace /tmp/kd/$f.asf --device cpu -w ao -W 480 -H 270 --stats 2>&1 | grep -E "steps per ray" | head -2 | sed "s/^/  cpu ao (primary, ao): /"
  done
done; done
date -u
