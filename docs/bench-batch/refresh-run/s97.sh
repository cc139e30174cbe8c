#!/bin/bash
# session 95c: the default (ratio 1.5, batch 16) against lower ratios (the slowest worlds refreshed continually); 100 steps each
export PYTHONUNBUFFERED=1
rm -rf $HOME/n97 && mkdir -p $HOME/n97 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n97/ && ln -sfn ../kernels $HOME/n97/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u97.log; nproc >> $R/u97.log
bb() { (cd $HOME/n97 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n97 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb97_$1 $2 2>&1 | tee $R/full97_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u97.log); echo "bb $1 done" >> $R/u97.log; }
bb def "--steps 100"
bb r10b16 "--steps 100 --world-ratio 1.0 --world-batch 16"
bb r10b32 "--steps 100 --world-ratio 1.0 --world-batch 32"
bb r12b16 "--steps 100 --world-ratio 1.25 --world-batch 16"
(cd $R && tar czf $HOME/bb97.tgz bb97_* full97_*)
cp $HOME/bb97.tgz $R/
echo "all done" >> $R/u97.log
