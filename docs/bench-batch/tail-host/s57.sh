#!/bin/bash
# session 57: bench_levels, the tail's tiers (work tree); batch_bench: the work tree (lazy report + tail) against
# c26ab95 (before both) and 2845e47 (the lazy report alone), alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n57 $HOME/o57 $HOME/h57 && mkdir -p $HOME/n57 $HOME/o57 $HOME/h57 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n57/ && ln -sfn ../kernels $HOME/n57/warpsoft/kernels
tar xzf .devpack/old57.tar.gz -C $HOME/o57 && ln -sfn ../kernels $HOME/o57/warpsoft/kernels
tar xzf .devpack/host57.tar.gz -C $HOME/h57 && ln -sfn ../kernels $HOME/h57/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
(cd $HOME/n57 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n57 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --tail default none 0.25,0.0625 0.125,0.03125,0.0078125 --out $R/levels57.json 2>&1 | sed "s/^/levels /" >> $R/u57.log)
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb57_$1 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u57.log); }
bb new0 $HOME/n57; bb old0 $HOME/o57; bb host0 $HOME/h57; bb new1 $HOME/n57; bb old1 $HOME/o57
echo "s57 done" >> $R/u57.log
