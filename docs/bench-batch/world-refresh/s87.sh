#!/bin/bash
# session 87: a world's factor made anew alone when its CG grew (per-world refresh), against 34ee1c1
export PYTHONUNBUFFERED=1
rm -rf $HOME/n87 $HOME/o83 && mkdir -p $HOME/n87 $HOME/o83 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n87/ && ln -sfn ../kernels $HOME/n87/warpsoft/kernels
tar xzf .devpack/old83.tar.gz -C $HOME/o83 && ln -sfn ../kernels $HOME/o83/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u87.log
nproc >> $R/u87.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb87_$1 $3 2>&1 | tee $R/full87_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u87.log); }
bb new $HOME/n87 ""
echo "bb new done" >> $R/u87.log
bb old $HOME/o83 ""
echo "bb old done" >> $R/u87.log
bb new12 $HOME/n87 "--world-floor 12"
echo "bb new12 done" >> $R/u87.log
bb newb $HOME/n87 ""
echo "all done" >> $R/u87.log
