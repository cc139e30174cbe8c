#!/bin/bash
# session 91b: a world's refresh submitted in one batch a boundary (one staging buffer, one snapshot of the
# rotations, cached views of the shared memory), the workers' analyses settled before the timed steps
export PYTHONUNBUFFERED=1
rm -rf $HOME/n92 && mkdir -p $HOME/n92 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n92/ && ln -sfn ../kernels $HOME/n92/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u92.log
bb() { (cd $HOME/n92 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n92 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb92_$1 $2 2>&1 | tee $R/full92_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u92.log); }
bb f10lag2 "--steps 10 --world-floor 10 --world-lag 2"
echo "bb f10lag2 done" >> $R/u92.log
bb off "--steps 10 --world-floor 0"
echo "bb off done" >> $R/u92.log
bb f10lag1 "--steps 10 --world-floor 10 --world-lag 1"
echo "bb f10lag1 done" >> $R/u92.log
bb f10lag2s30 "--steps 30 --world-floor 10 --world-lag 2"
echo "bb f10lag2s30 done" >> $R/u92.log
bb offs30 "--steps 30 --world-floor 0"
echo "all done" >> $R/u92.log
