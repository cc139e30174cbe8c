#!/bin/bash
# session 78: the assembled product's variants (prod78.py), then whole steps with the block CG's
# directions in float32 against float64, alternated
export PYTHONUNBUFFERED=1
rm -rf $HOME/n78 && mkdir -p $HOME/n78 && cp -r warpsoft kernels tools scenes pyproject.toml .devpack $HOME/n78/ && ln -sfn ../kernels $HOME/n78/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u78.log
(cd $HOME/n78 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n78 timeout 600 python3 .devpack/prod78.py 1024 $R/prod78.json cuda 2>&1 | grep -v "^Module" | sed "s/^/prod /" >> $R/u78.log)
echo "prod done" >> $R/u78.log
bb() { (cd $HOME/n78 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n78 timeout 900 python3 tools/batch_bench.py --device cuda --steps 10 --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --out $R/bb78_$1 $2 2>&1 | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u78.log); }
bb f32 "--directions float32 --kernels"
echo "bb f32 done" >> $R/u78.log
bb f64 "--directions float64 --kernels"
echo "bb f64 done" >> $R/u78.log
bb f32b "--directions float32"
bb f64b "--directions float64"
echo "all done" >> $R/u78.log
