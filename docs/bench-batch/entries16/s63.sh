#!/bin/bash
# session 63: the factors' entries in fewer bytes (uint16 columns, float16 values): bench_levels, then whole steps
export PYTHONUNBUFFERED=1
rm -rf $HOME/n63 $HOME/o63 && mkdir -p $HOME/n63 $HOME/o63 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n63/ && ln -sfn ../kernels $HOME/n63/warpsoft/kernels
tar xzf .devpack/old63.tar.gz -C $HOME/o63 && ln -sfn ../kernels $HOME/o63/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u63.log
(cd $HOME/n63 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n63 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --entries int32/float32 uint16/float32 int32/float16 uint16/float16 --out $R/levels63.json 2>&1 | sed "s/^/levels /" >> $R/u63.log)
echo "levels done" >> $R/u63.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb63_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u63.log); }
bb new0 $HOME/n63; bb f16_0 $HOME/n63 "--factor-values float16"; bb old0 $HOME/o63
echo "s63 done" >> $R/u63.log
