set -x
R=/tmp/ppo; rm -rf $R; mkdir -p $R
COMMON="--num-envs 128 --unroll-length 24 --batch-size 64 --minibatches 4 --no-evaluations --no-compile-cache"
/usr/bin/time -f "%e s wall" footforge train flat --feet aof --policy B --physics mujoco --out $R/flat_aof_mujoco $COMMON --timesteps 245760 --checkpoint-every 61440 > $R/flat_aof_mujoco.log 2>&1
/usr/bin/time -f "%e s wall" footforge train rough --feet aof --policy P --physics mujoco --out $R/rough_aof_P_mujoco $COMMON --timesteps 122880 --checkpoint-every 30720 > $R/rough_aof_P_mujoco.log 2>&1
/usr/bin/time -f "%e s wall" footforge train rough --feet aof --policy PH --physics mujoco --out $R/rough_aof_PH_mujoco --num-envs 8 --unroll-length 4 --batch-size 8 --minibatches 1 --timesteps 64 --checkpoint-every 32 --no-evaluations --no-compile-cache > $R/rough_aof_PH_tiny_mujoco.log 2>&1
/usr/bin/time -f "%e s wall" footforge train flat --feet aof --policy B --physics mjx --out $R/flat_aof_mjx $COMMON --timesteps 24576 --checkpoint-every 12288 > $R/flat_aof_mjx.log 2>&1
/usr/bin/time -f "%e s wall" footforge train rough --feet aof --policy P --physics mjx --out $R/rough_aof_P_mjx $COMMON --timesteps 12288 --checkpoint-every 6144 > $R/rough_aof_P_mjx.log 2>&1
