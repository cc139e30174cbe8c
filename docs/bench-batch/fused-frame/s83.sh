#!/bin/bash
# session 83: whole steps, the block CG entering and leaving the factors' frame in its update and Gram kernel, the small stages in the Gram kernels
# against 34ee1c1, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n83 $HOME/o83 && mkdir -p $HOME/n83 $HOME/o83 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n83/ && ln -sfn ../kernels $HOME/n83/warpsoft/kernels
tar xzf .devpack/old83.tar.gz -C $HOME/o83 && ln -sfn ../kernels $HOME/o83/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u83.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb83_$1 $3 2>&1 | tee $R/full_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u83.log); }
bb new $HOME/n83 "--kernels"
echo "bb new done" >> $R/u83.log
bb old $HOME/o83 "--kernels"
echo "bb old done" >> $R/u83.log
bb newb $HOME/n83 ""
bb oldb $HOME/o83 ""
echo "all done" >> $R/u83.log
