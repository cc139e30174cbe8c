#!/bin/bash
# session 78, last: bench.py one robot, this tree against 2641eb3, alternated twice
export PYTHONUNBUFFERED=1
rm -rf $HOME/n82 $HOME/o82 $HOME/devmesh && mkdir -p $HOME/n82 $HOME/o82 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n82/ && ln -sfn ../kernels $HOME/n82/warpsoft/kernels
tar xzf .devpack/old77.tar.gz -C $HOME/o82 && ln -sfn ../kernels $HOME/o82/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u82.log); }
b new0 $HOME/n82; b old0 $HOME/o82; b new1 $HOME/n82; b old1 $HOME/o82
echo "robots done" >> $R/u82.log
