#!/bin/bash
# session 102: the robots, with the single-world path back on memsets, against fd9e58e, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n102 $HOME/o99 $HOME/devmesh && mkdir -p $HOME/n102 $HOME/o99 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n102/ && ln -sfn ../kernels $HOME/n102/warpsoft/kernels
tar xzf .devpack/old99.tar.gz -C $HOME/o99 && ln -sfn ../kernels $HOME/o99/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 100 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u102.log); }
b new0 $HOME/n102; b old0 $HOME/o99
for i in 1 2 3; do b new$i $HOME/n102; b old$i $HOME/o99; done
echo "all done" >> $R/u102.log
