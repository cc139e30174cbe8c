#!/bin/bash
# session 67, fourth run: whole steps, panels against rows (the same tree), then panels by rows, spread and unroll
export PYTHONUNBUFFERED=1
rm -rf $HOME/n70 && mkdir -p $HOME/n70 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n70/ && ln -sfn ../kernels $HOME/n70/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u70.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb70_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u70.log); }
bb panels0 $HOME/n70 "--factor-layout panels"; bb rows0 $HOME/n70 "--factor-layout rows"
echo "bb done" >> $R/u70.log
(cd $HOME/n70 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n70 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --layout panels --panel-rows 4 2 --panel-spread 8,1 16,1 32,1 8,4 --panel-unroll 4 8 --out $R/levels70.json 2>&1 | sed "s/^/levels /" >> $R/u70.log)
echo "levels done" >> $R/u70.log
