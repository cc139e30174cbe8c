#!/bin/bash
# session 89: a world's factor made in worker processes beside the step (lag 1, 2), floors 10 and 12,
# against the refresh off; then one robot against 9cf8f5d
export PYTHONUNBUFFERED=1
rm -rf $HOME/n89 $HOME/o89 $HOME/devmesh && mkdir -p $HOME/n89 $HOME/o89 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n89/ && ln -sfn ../kernels $HOME/n89/warpsoft/kernels
tar xzf .devpack/old89.tar.gz -C $HOME/o89 && ln -sfn ../kernels $HOME/o89/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u89.log
nproc >> $R/u89.log
bb() { (cd $HOME/n89 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n89 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb89_$1 $2 2>&1 | tee $R/full89_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u89.log); }
bb f10lag1 "--world-floor 10 --world-lag 1"
echo "bb f10lag1 done" >> $R/u89.log
bb off "--world-floor 0"
echo "bb off done" >> $R/u89.log
bb f12lag1 "--world-floor 12 --world-lag 1"
echo "bb f12lag1 done" >> $R/u89.log
bb f10lag2 "--world-floor 10 --world-lag 2"
echo "bb f10lag2 done" >> $R/u89.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | sed "s/^/$1 /" >> $R/u89.log); }
b new0 $HOME/n89; b old0 $HOME/o89; b new1 $HOME/n89; b old1 $HOME/o89
echo "all done" >> $R/u89.log
