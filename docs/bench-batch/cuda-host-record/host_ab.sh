set -eu
export PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$PWD/.devmesh
mkdir -p $HOME/ab && tar xJf .devpack/old4dd.tar.xz -C $HOME/ab
ln -sfn ../kernels $HOME/ab/prev/warpsoft/kernels; ln -sfn ../kernels warpsoft/kernels
cp tools/batch_bench.py $HOME/ab/prev/tools/batch_bench.py  # the same bench (graph time) on both trees
run() { tree=$1; label=$2
  (cd $tree && PYTHONPATH=$HOME/dw:$tree timeout 280 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --sizes 256 1024 --out $OUT/$label 2>&1 | grep -E "^batch" | sed "s/^/$label /")
}
for x in "$@"; do case $x in new*) run $PWD $x;; old*) run $HOME/ab/prev $x;; esac; done
