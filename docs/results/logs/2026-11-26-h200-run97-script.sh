set -u
# Run 97: run 96 again with more rounds, 16 threads only: A 5580b69; B the larger of two big children always
# shared; C B and several parallel steps published at once. Interleaved, 8 rounds of 5 builds.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma
for d in 'ABC':
    open('.dev/ab/%s/libas.so.0' % d,'wb').write(lzma.open('.dev/ab/%s/libas.so.0.xz' % d).read())
"
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S=$PWD/.dev/scenes; S0=$(date +%s)
for sc in staircase.ply.zst bmw-m6.drc; do
 for r in 1 2 3 4 5 6 7 8; do for v in A B C; do
  echo -n "$v r$r "; LD_LIBRARY_PATH=$PWD/.dev/ab/$v:$PWD/.dev/lib timeout 60 .dev/ab/bl $S/$sc kd:sah 16 5
 done; done
 echo "(at $(( $(date +%s) - S0 )) s)"
done
date -u
