set -u
# Run 95: where a KD SAH build's 16 threads wait: a timeline of the nodes of 20,000 references or more (a build
# of 5580b69's driver with timers, not committed), staircase and bmw-m6 at 16, 8 and 2 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma
open('.dev/tl/libas.so.0','wb').write(lzma.open('.dev/tl/libas.so.0.xz').read())
"
mkdir -p $OUT; date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S=$PWD/.dev/scenes
for sc in staircase.ply.zst bmw-m6.drc; do for t in 16 8 2; do
  echo "== $sc $t threads"
  KDTL=1 LD_LIBRARY_PATH=$PWD/.dev/tl:$PWD/.dev/lib .dev/tl/bl $S/$sc kd:sah $t 2 > $OUT/tl-${sc%%.*}-$t.log 2>&1; grep -E "tree phase|busy|median" $OUT/tl-${sc%%.*}-$t.log
done; done
date -u
