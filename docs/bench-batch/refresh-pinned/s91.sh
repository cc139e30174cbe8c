#!/bin/bash
# session 91: a world's refresh with page-locked shared memory, copies on a side stream, workers forked
# with the first factorization and analysing ahead: floor 10 lag 1, off, profile, floor 10 lag 2, robots
# against 68a7b6a, then floor 12 lag 1
export PYTHONUNBUFFERED=1
rm -rf $HOME/n91 $HOME/o91 $HOME/devmesh && mkdir -p $HOME/n91 $HOME/o91 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n91/ && ln -sfn ../kernels $HOME/n91/warpsoft/kernels
tar xzf .devpack/old91.tar.gz -C $HOME/o91 && ln -sfn ../kernels $HOME/o91/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u91.log
nproc >> $R/u91.log
bb() { (cd $HOME/n91 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n91 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb91_$1 $2 2>&1 | tee $R/full91_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u91.log); }
bb f10lag1 "--world-floor 10 --world-lag 1"
echo "bb f10lag1 done" >> $R/u91.log
bb off "--world-floor 0"
echo "bb off done" >> $R/u91.log
(cd $HOME/n91 && cp $OLDPWD/.devpack/prof91.py . && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n91 timeout 600 python3 prof91.py > $R/prof91.log 2>&1)
echo "prof done" >> $R/u91.log
bb f10lag2 "--world-floor 10 --world-lag 2"
echo "bb f10lag2 done" >> $R/u91.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u91.log); }
b new0 $HOME/n91; b old0 $HOME/o91; b new1 $HOME/n91; b old1 $HOME/o91
echo "robots done" >> $R/u91.log
bb f12lag1 "--world-floor 12 --world-lag 1"
echo "all done" >> $R/u91.log
