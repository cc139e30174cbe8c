#!/bin/bash
# session 112: installs before the first graph again, their values staged beside the last step's graphs; check, then
# 1024 Diamonds alternated with 3c8b83e, then the robots
export PYTHONUNBUFFERED=1
rm -rf $HOME/n112 $HOME/o112 $HOME/bb $HOME/devmesh && mkdir -p $HOME/n112 $HOME/o112 $HOME/bb && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n112/ && ln -sfn ../kernels $HOME/n112/warpsoft/kernels
tar xzf .devpack/old112.tar.gz -C $HOME/o112 && ln -sfn ../kernels $HOME/o112/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u112.log; nproc >> $R/u112.log
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
(cd $HOME/n112 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n112 timeout 400 python3 $OLDPWD/.devpack/h112.py 2>&1 | tail -5 | sed "s/^/check /" >> $R/u112.log)
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full112_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u112.log); cp $HOME/bb/$1/batch.json $R/bb112_$1.json; python3 -c "import json;r=json.load(open('$R/bb112_$1.json'))['rows'][0];print('$1', 'mean', round(r['step_mean_ms'],2), 'median', round(r['step_ms'],2), 'graph', round(r['graph_ms'],2), 'refresh', round(r['refresh_ms'],2), 'run/s', round(r['run_design_steps_per_s']), 'cg', sum(r['step_cg_iterations']), 'refreshes', r['world_refreshes'], 'staged', r.get('refactor_staged'))" >> $R/u112.log; echo "bb $1 done" >> $R/u112.log; }
bb new0 $HOME/n112
bb old0 $HOME/o112
bb new1 $HOME/n112
bb old1 $HOME/o112
echo "batches done" >> $R/u112.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 100 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u112.log); }
for i in 0 1 2; do b new$i $HOME/n112; b old$i $HOME/o112; done
echo "all done" >> $R/u112.log
