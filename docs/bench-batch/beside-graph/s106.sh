#!/bin/bash
# session 106: where the host's share goes, timing on and off alternated (h106.py)
export PYTHONUNBUFFERED=1
rm -rf $HOME/n106 && mkdir -p $HOME/n106 && cp -r warpsoft kernels tools scenes pyproject.toml .devpack/h106.py $HOME/n106/ && ln -sfn ../kernels $HOME/n106/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u106.log; nproc >> $R/u106.log
(cd $HOME/n106 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n106 timeout 1200 python3 h106.py > $R/h106.log 2>&1)
echo "all done" >> $R/u106.log
