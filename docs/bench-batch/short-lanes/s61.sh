#!/bin/bash
# session 61: one step's kernels, each timed, at HEAD (the short rows' lanes)
export PYTHONUNBUFFERED=1
rm -rf $HOME/n61 && mkdir -p $HOME/n61 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n61/ && ln -sfn ../kernels $HOME/n61/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
(cd $HOME/n61 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n61 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --kernels --out $R/bb61_kernels 2>&1 | grep "batch \|Error\|error" >> $R/u61.log)
echo "s61 done" >> $R/u61.log
