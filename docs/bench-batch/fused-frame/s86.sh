#!/bin/bash
# session 83, third machine: is a kernel's cost additive in the captured step? 34ee1c1 with the
# factors' rotation in launched twice (the same numbers), against 34ee1c1, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/d86 $HOME/o83 && mkdir -p $HOME/d86 $HOME/o83
tar xzf .devpack/dbl.tar.gz -C $HOME/d86 && ln -sfn ../kernels $HOME/d86/warpsoft/kernels
tar xzf .devpack/old83.tar.gz -C $HOME/o83 && ln -sfn ../kernels $HOME/o83/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u86.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb86_$1 $3 2>&1 | tee $R/full86_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u86.log); }
bb dbl $HOME/d86 ""
echo "bb dbl done" >> $R/u86.log
bb old $HOME/o83 ""
echo "all done" >> $R/u86.log
