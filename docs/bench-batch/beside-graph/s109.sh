#!/bin/bash
# session 106: the refreshes beside the first graph, their values staged on the side stream, reads on the step's stream:
# the robots against 731d2f7, then batch runs (lag 1 and 2) alternated with 731d2f7
export PYTHONUNBUFFERED=1
rm -rf $HOME/n109 $HOME/o106 $HOME/bb $HOME/devmesh && mkdir -p $HOME/n109 $HOME/o106 $HOME/bb && cp -r warpsoft kernels tools scenes pyproject.toml $HOME/n109/ && ln -sfn ../kernels $HOME/n109/warpsoft/kernels
tar xzf .devpack/old106.tar.gz -C $HOME/o106 && ln -sfn ../kernels $HOME/o106/warpsoft/kernels
cp -r .devmesh $HOME/devmesh
R=$HOME/res; mkdir -p $R
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u109.log; nproc >> $R/u109.log
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 100 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u109.log); }
b new0 $HOME/n109; b old0 $HOME/o106
for i in 1 2; do b new$i $HOME/n109; b old$i $HOME/o106; done
echo "robots done" >> $R/u109.log
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full109_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u109.log); cp $HOME/bb/$1/batch.json $R/bb109_$1.json; python3 -c "import json;r=json.load(open('$R/bb109_$1.json'))['rows'][0];print('$1', 'mean', round(r['step_mean_ms'],2), 'median', round(r['step_ms'],2), 'graph', round(r['graph_ms'],2), 'refresh', round(r['refresh_ms'],2), 'run/s', round(r['run_design_steps_per_s']), 'cg', sum(r['step_cg_iterations']), 'refreshes', r['world_refreshes'])" >> $R/u109.log; echo "bb $1 done" >> $R/u109.log; }
bb lag1a $HOME/n109 "--world-lag 1"
bb old0 $HOME/o106
bb lag2a $HOME/n109 "--world-lag 2"
bb lag1b $HOME/n109 "--world-lag 1"
bb old1 $HOME/o106
echo "all done" >> $R/u109.log
