set -eu
export PYTHONUNBUFFERED=1 WARPSOFT_MESH_CACHE=$PWD/.devmesh PYTHONPATH=$HOME/dw:$PWD
ln -sfn ../kernels warpsoft/kernels
batch() { label=$1; shift; timeout 290 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --out $OUT/$label "$@" 2>&1 | grep -E "^batch|Error|error" | sed "s/^/$label /"; }
robots() { label=$1; shift; python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse grasper --out $OUT/$label "$@" 2>&1 | grep -E "^(finger|diamond|grasper)" | sed "s/^/$label /"; }
for x in "$@"; do case $x in
  bblock*) batch $x --sizes 256 1024;;
  bcol*) batch $x --sizes 256 1024 --column-cg;;
  rblock*) robots $x;;
  rcol*) robots $x --column-cg;;
  table*) batch $x --sizes 1 16 64 256 1024;;
esac; done
