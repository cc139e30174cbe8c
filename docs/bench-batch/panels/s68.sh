#!/bin/bash
# session 67, second run: panels with their sums spread over the lanes (a reduce-scatter), by rows, spread and unroll
export PYTHONUNBUFFERED=1
rm -rf $HOME/n68 && mkdir -p $HOME/n68 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n68/ && ln -sfn ../kernels $HOME/n68/warpsoft/kernels
rm -rf $HOME/devpack && cp -r .devpack $HOME/devpack
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u68.log
(cd $HOME/n68 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n68 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --layout rows panels --panel-rows 4 8 --panel-spread 1,1 2,1 4,1 8,1 --panel-unroll 2 4 --out $R/levels68.json 2>&1 | sed "s/^/levels /" >> $R/u68.log)
echo "levels done" >> $R/u68.log
