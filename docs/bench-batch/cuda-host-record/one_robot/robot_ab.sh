set -eu
export PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$PWD/.devmesh
mkdir -p $HOME/ab && tar xJf .devpack/old4dd.tar.xz -C $HOME/ab
ln -sfn ../kernels $HOME/ab/prev/warpsoft/kernels; ln -sfn ../kernels warpsoft/kernels
run() { tree=$1; label=$2
  (cd $tree && PYTHONPATH=$HOME/dw:$tree python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse grasper --out $OUT/$label 2>&1 | grep -E "^\| [a-z_]+ \| v2" | awk -F'|' -v l=$label '{print l, $2, $7, $10}')
}
for x in "$@"; do case $x in new*) run $PWD $x;; old*) run $HOME/ab/prev $x;; esac; done
