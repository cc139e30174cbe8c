#!/bin/bash
# session 103: wide panels in the tail (a block a panel): bench_levels variants, then a batch A/B against 6c9b31b
export PYTHONUNBUFFERED=1
rm -rf $HOME/n103 $HOME/o103 && mkdir -p $HOME/n103 $HOME/o103 && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n103/ && ln -sfn ../kernels $HOME/n103/warpsoft/kernels
tar xzf .devpack/old103.tar.gz -C $HOME/o103 && ln -sfn ../kernels $HOME/o103/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u103.log; nproc >> $R/u103.log
(cd $HOME/n103 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n103 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --per-level --wide none 256,128 128,128 512,256 256,256 128,64 64,64 --out $R/lv103.json > $R/lv103.log 2>&1)
grep -E "^panels|Error|error" $R/lv103.log >> $R/u103.log
echo "levels done" >> $R/u103.log
best=$(python3 -c "import json;r=json.load(open('$R/lv103.json'))['results'];b=min(r,key=lambda x:x['solve_ms']);w=b['wide'];print('none' if w is None else f'{int(w[0])},{w[1]}')" 2>/dev/null || echo none)
echo "best $best" >> $R/u103.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $R/bb103_$1 $3 2>&1 | tee $R/full103_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u103.log); echo "bb $1 done" >> $R/u103.log; }
bb new0 $HOME/n103 "--wide $best"
bb old0 $HOME/o103 ""
bb new1 $HOME/n103 "--wide $best"
echo "all done" >> $R/u103.log
