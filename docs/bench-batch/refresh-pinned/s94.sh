#!/bin/bash
# session 91d: one robot at 6c332b2 against 68a7b6a, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n94 $HOME/o91 $HOME/devmesh && mkdir -p $HOME/n94 $HOME/o91 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n94/ && ln -sfn ../kernels $HOME/n94/warpsoft/kernels
tar xzf .devpack/old91.tar.gz -C $HOME/o91 && ln -sfn ../kernels $HOME/o91/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u94.log); }
b new0 $HOME/n94; b old0 $HOME/o91; b new1 $HOME/n94; b old1 $HOME/o91
echo "all done" >> $R/u94.log
