#!/bin/bash
# session 95b: a boundary sends at most WORLD_BATCH blocks, the slowest worlds first; 100 steps each
export PYTHONUNBUFFERED=1
rm -rf $HOME/n96 && mkdir -p $HOME/n96 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n96/ && ln -sfn ../kernels $HOME/n96/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u96.log; nproc >> $R/u96.log
bb() { (cd $HOME/n96 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n96 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb96_$1 $2 2>&1 | tee $R/full96_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u96.log); echo "bb $1 done" >> $R/u96.log; }
bb b16 "--steps 100 --world-floor 10 --world-lag 2 --world-batch 16"
bb b0 "--steps 100 --world-floor 10 --world-lag 2 --world-batch 0"
bb b16r15 "--steps 100 --world-floor 10 --world-lag 2 --world-batch 16 --world-ratio 1.5"
bb b8 "--steps 100 --world-floor 10 --world-lag 2 --world-batch 8"
(cd $R && tar czf $HOME/bb96.tgz bb96_* full96_*)
cp $HOME/bb96.tgz $R/
echo "all done" >> $R/u96.log
