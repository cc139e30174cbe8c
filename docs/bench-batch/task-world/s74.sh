#!/bin/bash
# session 72, third machine: the panels' levels with the task holding its world, untested when all run,
# registers capped (bench_levels), then whole steps against 8db1cc8
export PYTHONUNBUFFERED=1
rm -rf $HOME/n74 $HOME/o74 && mkdir -p $HOME/n74 $HOME/o74 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n74/ && ln -sfn ../kernels $HOME/n74/warpsoft/kernels
tar xzf .devpack/old74.tar.gz -C $HOME/o74 && ln -sfn ../kernels $HOME/o74/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u74.log
(cd $HOME/n74 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n74 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --per-level --unchecked 1 0 --panel-registers 0 40 48 --panel-spread 8,1 16,1 --out $R/levels74.json 2>&1 | grep -v "^level " | sed "s/^/levels /" >> $R/u74.log)
echo "levels done" >> $R/u74.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb74_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u74.log); }
bb new $HOME/n74 ""
echo "bb new done" >> $R/u74.log
bb old $HOME/o74 ""
echo "all done" >> $R/u74.log
