#!/bin/bash
# session 78, third machine: whole steps with the assembled blocks in chunks of 32 rows (sliced ELLPACK)
# against c6c1019 (rows compressed; the block CG's directions in float32 in both), alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n81 $HOME/o78 && mkdir -p $HOME/n81 $HOME/o78 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n81/ && ln -sfn ../kernels $HOME/n81/warpsoft/kernels
tar xzf .devpack/old78.tar.gz -C $HOME/o78 && ln -sfn ../kernels $HOME/o78/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u81.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb81_$1 $3 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u81.log); }
bb new $HOME/n81 "--kernels"
echo "bb new done" >> $R/u81.log
bb old $HOME/o78 "--kernels"
echo "bb old done" >> $R/u81.log
bb newb $HOME/n81 ""
bb oldb $HOME/o78 ""
echo "all done" >> $R/u81.log
