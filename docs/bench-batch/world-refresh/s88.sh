#!/bin/bash
# session 87: bench.py one robot, this tree (c86b921) against 34ee1c1, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n88 $HOME/o88 $HOME/devmesh && mkdir -p $HOME/n88 $HOME/o88 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n88/ && ln -sfn ../kernels $HOME/n88/warpsoft/kernels
tar xzf .devpack/old83.tar.gz -C $HOME/o88 && ln -sfn ../kernels $HOME/o88/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u88.log); }
b new0 $HOME/n88; b old0 $HOME/o88; b new1 $HOME/n88; b old1 $HOME/o88
echo "robots done" >> $R/u88.log
