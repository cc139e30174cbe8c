#!/bin/bash
# session 72: whole steps with each kernel timed (the small kernels unrolled, against 5146b6a), then each level's time
export PYTHONUNBUFFERED=1
rm -rf $HOME/n72 $HOME/o72 && mkdir -p $HOME/n72 $HOME/o72 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n72/ && ln -sfn ../kernels $HOME/n72/warpsoft/kernels
tar xzf .devpack/old72.tar.gz -C $HOME/o72 && ln -sfn ../kernels $HOME/o72/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u72.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb72_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u72.log); }
bb new $HOME/n72 "--kernels"
echo "bb new done" >> $R/u72.log
(cd $HOME/n72 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n72 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --per-level --out $R/levels72.json 2>&1 | sed "s/^/levels /" >> $R/u72.log)
echo "levels done" >> $R/u72.log
bb old $HOME/o72 "--kernels"
echo "all done" >> $R/u72.log
