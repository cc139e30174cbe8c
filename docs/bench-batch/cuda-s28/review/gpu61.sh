ls $HOME/dw/warp >/dev/null 2>&1 || (cat $HOME/dw/part00 .devpack/part01 | tar x -C $HOME/dw && xz -dc $HOME/dw/warp.tar.xz | tar x -C $HOME/dw && python3 -m pip install -q --no-index --no-deps --target $HOME/dw $HOME/dw/*.whl)
export PYTHONPATH=$HOME/dw:$PWD PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$HOME/dw/devmesh
ln -sfn ../kernels warpsoft/kernels
mkdir -p $HOME/dw/devmesh; cp -n .devpack/mesh/*.npz .devpack/mesh4/*.npz $HOME/dw/devmesh/ 2>/dev/null
[ -d $HOME/h64 ] || (mkdir -p /tmp/x && xz -dc .devpack/6435ac1.tar.xz | tar x -C /tmp/x && mv /tmp/x/prev $HOME/h64 && ln -sfn ../kernels $HOME/h64/warpsoft/kernels)
mkdir -p $OUT/ab $OUT/batch
S="diamond_inverse finger"
A="--steps 40 --warmup 10"
for r in 1 2; do
timeout 100 python3 tools/bench.py --device cuda $A --scenes $S --out $OUT/ab/new$r > $OUT/ab/new$r.log 2>&1
(cd $HOME/h64 && PYTHONPATH=$HOME/dw:$HOME/h64 timeout 100 python3 tools/bench.py --device cuda $A --scenes $S --out $OUT/ab/prev$r > $OUT/ab/prev$r.log 2>&1)
done
for f in new1 prev1 new2 prev2; do echo "== $f"; grep -hE "^\| (finger|diamond_inverse) \| v2" $OUT/ab/$f.log | awk -F'|' '{print $2, $7, $9}'; done
