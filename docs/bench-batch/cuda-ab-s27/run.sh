ls $HOME/dw/warp >/dev/null 2>&1 || (cat $HOME/dw/part00 .devpack/part01 | tar x -C $HOME/dw && xz -dc $HOME/dw/warp.tar.xz | tar x -C $HOME/dw && python3 -m pip install -q --no-index --no-deps --target $HOME/dw $HOME/dw/*.whl)
export PYTHONPATH=$HOME/dw:$PWD PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$HOME/dw/devmesh
ln -sfn ../kernels warpsoft/kernels
mkdir -p $HOME/dw/devmesh; cp .devpack/mesh/*.npz $HOME/dw/devmesh/
[ -d $HOME/old ] || (xz -dc .devpack/dedf257.tar.xz | tar x -C $HOME && ln -sfn ../kernels $HOME/old/warpsoft/kernels)
mkdir -p $OUT/ab
S="diamond_inverse finger"
A="--steps 40 --warmup 10"
for r in 1 2; do
timeout 110 python3 tools/bench.py --device cuda $A --scenes $S --out $OUT/ab/new$r > $OUT/ab/new$r.log 2>&1
(cd $HOME/old && PYTHONPATH=$HOME/dw:$HOME/old timeout 110 python3 tools/bench.py --device cuda $A --scenes $S --out $OUT/ab/old$r > $OUT/ab/old$r.log 2>&1)
done
for f in new1 old1 new2 old2; do echo "== $f"; grep -E "^\| [a-z_]+ \| v2" $OUT/ab/$f/bench.md | awk -F'|' 'NF>12 {print $2, $7}'; tail -n 2 $OUT/ab/$f.log; done
