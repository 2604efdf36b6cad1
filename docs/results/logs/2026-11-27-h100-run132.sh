set -u
# Run 132: 16 threads, paired A/B against c36 (9eda610): q6 = binned shares right children down to 256 (1,024), q7 = SBVH shares down to 256 (1,024).
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for L,z in [('c36','z22'),('q6','z23'),('q7','z23')]:
    os.makedirs('/tmp/'+L,exist_ok=True); open('/tmp/'+L+'/libas.so.0','wb').write(lzma.open('.dev/'+z+'/'+L+'.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
echo "== c36 vs q6"
for a in "bunny.ply.zst bvh:sah 41" "staircase2.ply.zst bvh:sah 41" "staircase.ply.zst bvh:sah 31" "bathroom.drc bvh:sah 21" "bmw-m6.drc bvh:sah 15"; do set -- $a
  timeout 60 $Z/abdl /tmp/c36 /tmp/q6 $S/$1 $2 16 $3 | sed 's/.*scenes.//'
done
echo "== c36 vs q7"
for a in "bunny.ply.zst bvh:sbvh 21" "staircase2.ply.zst bvh:sbvh 31" "staircase.ply.zst bvh:sbvh 15"; do set -- $a
  timeout 60 $Z/abdl /tmp/c36 /tmp/q7 $S/$1 $2 16 $3 | sed 's/.*scenes.//'
done
date -u
