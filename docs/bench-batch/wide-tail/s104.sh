#!/bin/bash
# session 104: a world's block walks the tail's levels (fused) with wide panels: bench_levels variants, then a batch A/B against 6c9b31b
export PYTHONUNBUFFERED=1
rm -rf $HOME/n104 $HOME/o103 $HOME/bb && mkdir -p $HOME/n104 $HOME/o103 $HOME/bb && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n104/ && ln -sfn ../kernels $HOME/n104/warpsoft/kernels
tar xzf .devpack/old103.tar.gz -C $HOME/o103 && ln -sfn ../kernels $HOME/o103/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u104.log; nproc >> $R/u104.log
(cd $HOME/n104 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n104 timeout 900 python3 tools/bench_levels.py --designs 1024 --unroll 4 --per-level --wide 256,128 none --fuse none 64,256 64,512 256,256 16,256 --out $R/lv104.json > $R/lv104.log 2>&1)
grep -E "^panels|Error|error|^tail levels" $R/lv104.log | sed 's/spread.*wide/wide/; s/entries.*P^-1/P^-1/' >> $R/u104.log
echo "levels done" >> $R/u104.log
best=$(python3 -c "import json;r=json.load(open('$R/lv104.json'))['results'];b=min(r,key=lambda x:x['solve_ms']);w=b['wide'];f=b['fuse'];print(('--wide none' if w is None else f'--wide {int(w[0])},{w[1]}')+' '+('--fuse none' if f is None else f'--fuse {f[0]},{f[1]}'))" 2>/dev/null || echo "--fuse none")
echo "best $best" >> $R/u104.log
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full104_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u104.log); cp $HOME/bb/$1/batch.json $R/bb104_$1.json; echo "bb $1 done" >> $R/u104.log; }
bb new0 $HOME/n104 "$best"
bb old0 $HOME/o103 ""
bb new1 $HOME/n104 "$best"
bb wideonly2 $HOME/n104 "--wide 256,128 --fuse none"
echo "all done" >> $R/u104.log
