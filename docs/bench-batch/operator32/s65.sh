#!/bin/bash
# session 65: the assembled blocks in float32 (operator_precision) against float64, whole steps
export PYTHONUNBUFFERED=1
rm -rf $HOME/n65 && mkdir -p $HOME/n65 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n65/ && ln -sfn ../kernels $HOME/n65/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u65.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb65_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u65.log); }
bb f32_0 $HOME/n65 "--operator-precision float32"; bb f64_0 $HOME/n65
echo "s65 done" >> $R/u65.log
