#!/bin/bash
# session 67: the factors' levels as panels (a supernode's rows reading their columns once) against rows
export PYTHONUNBUFFERED=1
rm -rf $HOME/n67 && mkdir -p $HOME/n67 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n67/ && ln -sfn ../kernels $HOME/n67/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u67.log
(cd $HOME/n67 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n67 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --layout rows panels --panel-spread 4,1 2,1 8,1 4,4 --panel-unroll 1 2 --out $R/levels67.json 2>&1 | sed "s/^/levels /" >> $R/u67.log)
echo "levels done" >> $R/u67.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb67_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u67.log); }
bb panels0 $HOME/n67 "--factor-layout panels"; bb rows0 $HOME/n67 "--factor-layout rows"
echo "s67 done" >> $R/u67.log
