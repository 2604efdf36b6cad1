set -u
# Run 154: build after build in a fresh process, 16 threads: time in ms and (page faults), at the
# commit in .dev/commit (seq_static) and with 1 GB of kept temporaries (seq_1g).
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b16',exist_ok=True)
for n in ['seq_static','seq_1g']:
    open('/tmp/b16/'+n,'wb').write(lzma.open('.dev/z/'+n+'.xz').read()); os.chmod('/tmp/b16/'+n,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); at $(cat .dev/commit)"
for b in seq_static seq_1g; do for spec in "bmw-m6.drc kd sah" "bathroom.drc kd sah" "bmw-m6.drc bvh sbvh" "bmw-m6.drc bvh sah" "bunny.ply.zst kd sah"; do
set -- $spec
echo "$b $1 $2:$3: $(/tmp/b16/$b $S/$1 $2 $3 16 8)"
done; done
date -u
