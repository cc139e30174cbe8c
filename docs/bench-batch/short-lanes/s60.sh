#!/bin/bash
export PYTHONUNBUFFERED=1
rm -rf $HOME/n60 $HOME/o60 && mkdir -p $HOME/n60 $HOME/o60 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n60/ && ln -sfn ../kernels $HOME/n60/warpsoft/kernels
tar xzf .devpack/old59.tar.gz -C $HOME/o60 && ln -sfn ../kernels $HOME/o60/warpsoft/kernels
R=$HOME/res; mkdir -p $R
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb60_$1 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u60.log); }
bb new0 $HOME/n60; bb old0 $HOME/o60; bb new1 $HOME/n60; bb old1 $HOME/o60
echo "s60 done" >> $R/u60.log
