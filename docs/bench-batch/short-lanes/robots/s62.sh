#!/bin/bash
# session 62: bench.py, one robot, new tree against c66944b, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n62 $HOME/o62 $HOME/devmesh && mkdir -p $HOME/n62 $HOME/o62 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n62/ && ln -sfn ../kernels $HOME/n62/warpsoft/kernels
tar xzf .devpack/old59.tar.gz -C $HOME/o62 && ln -sfn ../kernels $HOME/o62/warpsoft/kernels
cp -r .devmesh $HOME/devmesh; rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u62.log); }
b new0 $HOME/n62; b old0 $HOME/o62; b new1 $HOME/n62; b old1 $HOME/o62
echo "s62 done" >> $R/u62.log
