set -u
# Run 134: clock_gettime cost and clocksource; system time of binned SAH builds at 16 threads, c33 (5b41486, threads sleep at once) vs c37 (e91e646, threads watch 100 us).
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for L in ['c33','c37']:
    os.makedirs('/tmp/'+L,exist_ok=True); open('/tmp/'+L+'/libas.so.0','wb').write(lzma.open('.dev/z23/'+L+'.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"; cat /sys/devices/system/clocksource/clocksource0/current_clocksource /sys/devices/system/clocksource/clocksource0/available_clocksource 2>&1
$Z/ct
for L in c33 c37 c33 c37; do for a in "bunny.ply.zst 60" "bathroom.drc 12"; do set -- $a
echo "$L $1: $(LD_LIBRARY_PATH=/tmp/$L:$LD_LIBRARY_PATH $Z/loopf $S/$1 bvh sah 16 $2 | tail -5 | tr '\n' ';')"
done; done
for L in c33 c37; do for w in 100 10000; do echo "$L $(LD_LIBRARY_PATH=/tmp/$L:$LD_LIBRARY_PATH $Z/prl 16 2000 $w | head -1)"; done; done
date -u
