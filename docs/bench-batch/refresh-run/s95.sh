#!/bin/bash
# session 95: the refactorizing workers niced (10) against not (0); 100 steps (a sweep's whole run), off and ratio 1.5 beside
export PYTHONUNBUFFERED=1
rm -rf $HOME/n95 $HOME/o91 $HOME/devmesh && mkdir -p $HOME/n95 $HOME/o91 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n95/ && ln -sfn ../kernels $HOME/n95/warpsoft/kernels
tar xzf .devpack/old91.tar.gz -C $HOME/o91 && ln -sfn ../kernels $HOME/o91/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u95.log; nproc >> $R/u95.log
bb() { (cd $HOME/n95 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n95 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb95_$1 $2 2>&1 | tee $R/full95_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u95.log); echo "bb $1 done" >> $R/u95.log; }
bb n10 "--steps 100 --world-floor 10 --world-lag 2 --worker-nice 10"
bb n0 "--steps 100 --world-floor 10 --world-lag 2 --worker-nice 0"
bb off "--steps 100"
bb r15 "--steps 100 --world-floor 10 --world-lag 2 --world-ratio 1.5 --worker-nice 10"
(cd $R && tar czf $HOME/bb95.tgz bb95_* full95_*)
cp $HOME/bb95.tgz $R/
echo "batch done" >> $R/u95.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u95.log); }
b new0 $HOME/n95; b old0 $HOME/o91; b new1 $HOME/n95; b old1 $HOME/o91
echo "all done" >> $R/u95.log
