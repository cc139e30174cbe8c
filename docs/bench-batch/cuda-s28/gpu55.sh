ls $HOME/dw/warp >/dev/null 2>&1 || (cat $HOME/dw/part00 .devpack/part01 | tar x -C $HOME/dw && xz -dc $HOME/dw/warp.tar.xz | tar x -C $HOME/dw && python3 -m pip install -q --no-index --no-deps --target $HOME/dw $HOME/dw/*.whl)
export PYTHONPATH=$HOME/dw:$PWD PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$HOME/dw/devmesh
ln -sfn ../kernels warpsoft/kernels
mkdir -p $HOME/dw/devmesh; cp .devpack/mesh/*.npz .devpack/mesh4/*.npz $HOME/dw/devmesh/
[ -d $HOME/prev ] || (xz -dc .devpack/e4525fd.tar.xz | tar x -C $HOME && ln -sfn ../kernels $HOME/prev/warpsoft/kernels)
mkdir -p $OUT/batch
B="--device cuda --steps 10 --warmup 3 --share-tolerance 0.01"
for r in 1 2; do
timeout 140 python3 tools/batch_bench.py $B --sizes $SIZES --out $OUT/batch/new$r 2>&1 | grep "^batch" | sed "s/^/new$r /"
(cd $HOME/prev && PYTHONPATH=$HOME/dw:$HOME/prev timeout 140 python3 tools/batch_bench.py $B --sizes $SIZES --out $OUT/batch/prev$r 2>&1 | grep "^batch" | sed "s/^/prev$r /")
done
