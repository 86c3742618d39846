% STUDY_REMOTE  The published study's session with its remote API, against
% `spm serve`: read the joint positions, set theta = [60 90 120] deg and read the
% state back, check theta = [60 90 220] deg (the links that collide there), try to
% set it (refused with 409, nothing moves). Runs in MATLAB and in GNU Octave:
%
%   spm serve                                     (in another terminal)
%   octave --no-gui --path examples/remote_matlab --eval study_remote
%
% Another server: set base_url first, e.g.
%   octave --path examples/remote_matlab --eval "base_url = 'http://robot-pc:8750'; study_remote"
% (with a token: the environment variable SPM_TOKEN).
if ~exist('base_url', 'var')
  base_url = 'http://127.0.0.1:8750';
end

joints = spm_get(base_url, '/joints');
fprintf('joints_deg: %.9f %.9f %.9f\n', joints.theta_deg);

[state, status] = spm_put(base_url, '/joints', struct('theta_deg', [60 90 120]));
fprintf('set_status: %d\n', status);
state = spm_get(base_url, '/state');
fprintf('state_theta_deg: %.9f %.9f %.9f\n', state.theta_deg);
fprintf('state_rpy_deg: %.9f %.9f %.9f\n', state.rpy_deg);
fprintf('state_reachable: %d\n', state.reachable);
fprintf('state_pairs: %s\n', spm_pairs(state.pairs));
collisions = spm_get(base_url, '/collisions');
fprintf('collision: %d\n', collisions.collision);

[verdict, status] = spm_post(base_url, '/check', struct('theta_deg', [60 90 220]));
fprintf('check_status: %d\n', status);
fprintf('check_safe: %d\n', verdict.safe);
fprintf('check_pairs: %s\n', spm_pairs(verdict.pairs));

[refusal, status] = spm_put(base_url, '/joints', struct('theta_deg', [60 90 220]));
fprintf('refused_status: %d\n', status);
fprintf('refused_checks: %s\n', strjoin({refusal.failed.check}, ' '));
joints = spm_get(base_url, '/joints');
fprintf('joints_after_deg: %.9f %.9f %.9f\n', joints.theta_deg);
