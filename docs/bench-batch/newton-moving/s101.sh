#!/bin/bash
# session 101 (a new machine: the old first): a later Newton iteration relinearizes the worlds that moved alone, against fd9e58e; 100 steps each, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n100 $HOME/o99 $HOME/devmesh && mkdir -p $HOME/n100 $HOME/o99 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n100/ && ln -sfn ../kernels $HOME/n100/warpsoft/kernels
tar xzf .devpack/old99.tar.gz -C $HOME/o99 && ln -sfn ../kernels $HOME/o99/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u101.log; nproc >> $R/u101.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $R/bb101_$1 2>&1 | tee $R/full101_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u101.log); echo "bb $1 done" >> $R/u101.log; }
bb old0 $HOME/o99
bb new1 $HOME/n100
(cd $R && tar czf $HOME/bb101.tgz bb101_* full101_*)
cp $HOME/bb101.tgz $R/
echo "batch done" >> $R/u101.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u101.log); }
b new0 $HOME/n100; b old0 $HOME/o99; b new1 $HOME/n100; b old1 $HOME/o99
echo "all done" >> $R/u101.log
