#!/bin/bash
# session 105: the robots (the wide tail panels do not run for one world) against 6c9b31b, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n105 $HOME/o103 $HOME/devmesh && mkdir -p $HOME/n105 $HOME/o103 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n105/ && ln -sfn ../kernels $HOME/n105/warpsoft/kernels
tar xzf .devpack/old103.tar.gz -C $HOME/o103 && ln -sfn ../kernels $HOME/o103/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 100 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u105.log); }
b new0 $HOME/n105; b old0 $HOME/o103
for i in 1 2; do b new$i $HOME/n105; b old$i $HOME/o103; done
echo "all done" >> $R/u105.log
