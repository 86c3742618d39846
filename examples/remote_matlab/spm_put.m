function [answer, status] = spm_put(base_url, resource, body)
%SPM_PUT  PUT a JSON body to a resource of an spm-pin server.
%   [state, status] = spm_put('http://127.0.0.1:8750', '/joints', ...
%                             struct('theta_deg', [60 90 120]))
%
%   status is the HTTP status: 200 when the twin moved, 409 when the safety guard
%   refused the goal (then nothing moved), 422 for a malformed body.
%   See spm_request for how MATLAB and GNU Octave send the body.
  [answer, status] = spm_request('PUT', base_url, resource, body);
end
