#!/bin/bash
# session 91c: the analyses ahead find the panels too; each job timed in its worker
# rotations, cached views of the shared memory), the workers' analyses settled before the timed steps
export PYTHONUNBUFFERED=1
rm -rf $HOME/n93 && mkdir -p $HOME/n93 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n93/ && ln -sfn ../kernels $HOME/n93/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u93.log
bb() { (cd $HOME/n93 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n93 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb93_$1 $2 2>&1 | tee $R/full93_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u93.log); }
bb f10lag2 "--steps 10 --world-floor 10 --world-lag 2"
echo "bb f10lag2 done" >> $R/u93.log
bb f10lag1 "--steps 10 --world-floor 10 --world-lag 1"
echo "bb f10lag1 done" >> $R/u93.log
bb f10lag2s30 "--steps 30 --world-floor 10 --world-lag 2"
(cd $R && tar czf $HOME/bb93.tgz bb93_*)
echo "all done" >> $R/u93.log
